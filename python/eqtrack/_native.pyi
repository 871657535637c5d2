"""Type stubs of eqtrack's native module (Rust, PyO3)."""

from typing import Any, Dict, List, Mapping, Optional, Tuple, Union
import os

import numpy as np
import numpy.typing as npt

_Scenario = Union[str, "os.PathLike[str]"]
_Array = npt.ArrayLike
_F64 = npt.NDArray[np.float64]

def simulate(
    scenario: _Scenario, overrides: Optional[Mapping[str, Any]] = None
) -> Tuple[List[str], List[_F64], str]: ...
def builtin_scenario(name: str) -> str: ...
def scenario_text(
    scenario: Optional[_Scenario], overrides: Optional[Mapping[str, Any]] = None
) -> Optional[str]: ...
def montecarlo(
    scenario: Optional[str], runs: int, seed: int, laws: List[str], threads: Optional[int] = None
) -> Dict[str, Any]: ...
def montecarlo_shard(
    scenario: Optional[str], runs: int, seed: int, laws: List[str], index: int, count: int
) -> bytes: ...
def montecarlo_merge(
    scenario: Optional[str], runs: int, seed: int, laws: List[str], shards: List[bytes]
) -> Dict[str, Any]: ...

class Controller:
    """The scenario's controller: its law, gains, model inertia and torque limit."""

    def __init__(self, scenario: _Scenario, overrides: Optional[Mapping[str, Any]] = None) -> None: ...
    @property
    def group(self) -> str: ...
    def compute(
        self, q: _Array, v: _Array, q_d: _Array, v_d: _Array, tau_d: Optional[_Array] = None
    ) -> Tuple[_F64, float]:
        """The torque and the Lyapunov function at (q, v) against (q_d, v_d, tau_d)."""

class ComplementaryFilter:
    """The complementary filter on SO(3) with gyro bias."""

    def __init__(self, kp: float, ki: float, world: _Array, weights: _Array) -> None: ...
    def step(self, h: float, gyro: _Array, directions: _Array) -> Tuple[_F64, _F64, _F64, bool]:
        """One step: (R_hat, rate, bias, started)."""

class EquivariantFilter:
    """The equivariant filter on SO(3) with gyro bias."""

    def __init__(self, gyro_noise: float, bias_walk: float, world: _Array, direction_noise: _Array) -> None: ...
    def step(self, h: float, gyro: _Array, directions: _Array) -> Tuple[_F64, _F64, _F64, bool]:
        """One step: (R_hat, rate, bias, started)."""
    @property
    def covariance(self) -> _F64: ...

class Allocator:
    """A vehicle's allocator, from its scenario's [vehicle]."""

    def __init__(self, scenario: _Scenario, overrides: Optional[Mapping[str, Any]] = None) -> None: ...
    @property
    def count(self) -> int: ...
    def allocate(self, demand: _Array) -> Tuple[_F64, _F64, int]:
        """(u_cmd, B u_cmd, status code)."""

class Detector:
    """A vehicle's allocation with its failure detector, from a scenario with [vehicle] and
    [fault_detection], stepped as the controller steps it."""

    def __init__(self, scenario: _Scenario, overrides: Optional[Mapping[str, Any]] = None) -> None: ...
    @property
    def count(self) -> int: ...
    @property
    def failed(self) -> List[int]: ...
    def step(
        self,
        t: float,
        q: _Array,
        v: _Array,
        wrench: _Array,
        applied: Optional[_Array] = None,
        follows: bool = True,
    ) -> Dict[str, Any]:
        """One control period: u_cmd, demand, achieved, accounted, status, alarms, suspect,
        statistic and detection (None, or actuator, kind, value and refined)."""
