//! The builders that turn a validated [`Scenario`] into the controller crate's objects, and the scenario's fingerprint.

use crate::{
    BUILTINS, PathKind, Scenario, ScenarioError, StateSpec, Validator, build_path, parse_law,
};
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::group::so3::exp_so3;
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::reference::{AxisTorque, CosTerm, Feedforward};
use eqtrack_controller::{
    Controller, ControllerConfig, ErrorFrame, Law, Path as GroupPath, PathReference, Reference,
    Source,
};
use nalgebra::{SMatrix, SVector, Vector3};
use std::path::Path;

impl Scenario {
    /// Loads a built-in scenario by name.
    pub fn builtin(name: &str) -> Result<Scenario, ScenarioError> {
        let (_, text) = BUILTINS
            .iter()
            .find(|(n, _)| *n == name)
            .ok_or_else(|| ScenarioError::UnknownBuiltin(name.to_owned()))?;
        Scenario::from_toml(text, &format!("built-in scenario `{name}`"), name)
    }

    /// A scenario file's text and the name it gives a scenario without `name` (the file's
    /// stem); what [`Scenario::from_file`] parses, for a caller that edits the text first.
    pub fn read_file(path: &Path) -> Result<(String, String), ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scenario".to_owned());
        Ok((text, stem))
    }

    /// Loads and validates a scenario file.
    pub fn from_file(path: &Path) -> Result<Scenario, ScenarioError> {
        let (text, stem) = Scenario::read_file(path)?;
        Validator {
            origin: &path.display().to_string(),
            base: path.parent(),
        }
        .parse(&text, &stem)
    }

    /// Parses and validates TOML text; `origin` names it in errors, `default_name` is used
    /// when the file has no `name`.
    pub fn from_toml(
        text: &str,
        origin: &str,
        default_name: &str,
    ) -> Result<Scenario, ScenarioError> {
        Validator { origin, base: None }.parse(text, default_name)
    }

    /// [`Scenario::from_toml`] for text read from a file in `base` (its waypoint files are
    /// relative to it), as [`Scenario::from_file`] parses the file's own text.
    pub fn from_toml_in(
        text: &str,
        origin: &str,
        default_name: &str,
        base: Option<&Path>,
    ) -> Result<Scenario, ScenarioError> {
        Validator { origin, base }.parse(text, default_name)
    }

    /// Overrides the law (checked against the group).
    pub fn with_law(mut self, law: Law) -> Result<Scenario, ScenarioError> {
        self.law = parse_law(law.name(), self.group, "--law", "the command line")?;
        Ok(self)
    }

    /// The error frame EqT flies when it is not the papers' world frame (`"reference"`,
    /// `"recentred"`); `None` for the world frame and for the comparison laws, which have no
    /// other. Summaries and the printed run line name it.
    pub fn error_frame_note(&self) -> Option<&'static str> {
        (self.law == Law::Eqt && self.error_frame != ErrorFrame::World)
            .then(|| self.error_frame.name())
    }

    /// The law as a run's first line names it: `eqt` (the papers' form, or a comparison law),
    /// or EqT with its error frame and what that makes of it, e.g. `eqt, error frame reference
    /// (the transported-velocity-error law, not the papers' form)`.
    pub fn law_label(&self) -> String {
        match self.error_frame_note() {
            None => self.law.name().to_owned(),
            Some(f) => format!(
                "{}, error frame {f} ({})",
                self.law.name(),
                match self.error_frame {
                    ErrorFrame::Recentred => "the papers' law evaluated at the reference pose",
                    _ => "the transported-velocity-error law, not the papers' form",
                }
            ),
        }
    }

    /// The number of control steps N = duration / control_period.
    pub fn steps(&self) -> u64 {
        (self.duration / self.control_period).round() as u64
    }

    /// n×n configuration from a [`StateSpec`]: SO(3) `exp(rotation)`; SE(3)
    /// `[[exp(rotation), position], [0, 1]]`; SE(2) `[[R(θ), (x, y)], [0, 1]]`.
    ///
    /// An SE(2) state is stored as the rotation `(0, 0, θ)` and the position `(x, y, 0)`, so
    /// its `exp` is the rotation about z whose third row and column are exactly `(0, 0, 1)`;
    /// the position then takes the third column. An SO(3) state never has a position (the
    /// scenario refuses one), so a 3 × 3 configuration with a non-zero position is SE(2)'s.
    pub fn configuration<const N: usize>(spec: &StateSpec) -> SMatrix<f64, N, N> {
        let r = exp_so3(&Vector3::from(spec.rotation));
        let mut q = SMatrix::<f64, N, N>::identity();
        for i in 0..3.min(N) {
            for j in 0..3.min(N) {
                q[(i, j)] = r[(i, j)];
            }
            if N > 3 {
                q[(i, N - 1)] = spec.position[i];
            }
        }
        if N == 3 && (spec.position[0] != 0.0 || spec.position[1] != 0.0) {
            q[(0, 2)] = spec.position[0];
            q[(1, 2)] = spec.position[1];
        }
        q
    }

    /// The controller configuration (validated again by [`Controller::new`]). The one place
    /// where the file's `controller.kp` becomes the law's `K` (`ControllerConfig::k`).
    pub fn controller_config<const N: usize, const M: usize>(&self) -> ControllerConfig<f64, N, M> {
        ControllerConfig {
            law: self.law,
            error_frame: self.error_frame,
            inertia: SMatrix::from_row_slice(&self.model_inertia),
            k: SMatrix::from_row_slice(&self.kp),
            kd: SMatrix::from_row_slice(&self.kd),
            torque_limit: self
                .torque_limit
                .as_ref()
                .map(|l| SVector::from_row_slice(l)),
        }
    }

    /// The controller.
    pub fn controller<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Controller<f64, G, N, M>, eqtrack_controller::Error> {
        Controller::new(self.controller_config())
    }

    /// The feedforward torque.
    pub fn feedforward<const M: usize>(
        &self,
    ) -> Result<Feedforward<f64, M>, eqtrack_controller::Error> {
        let mut ff = Feedforward::<f64, M>::zero();
        for (i, axis) in self.feedforward.iter().enumerate().take(M) {
            let terms: Vec<CosTerm<f64>> = axis
                .terms
                .iter()
                .map(|t| CosTerm {
                    amplitude: t.amplitude,
                    frequency: t.frequency,
                    phase: t.phase,
                })
                .collect();
            ff.axes[i] = AxisTorque::new(i, axis.offset, &terms)?;
        }
        Ok(ff)
    }

    /// The reference generator (model inertia, control period, reference substeps).
    pub fn reference_generator<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Reference<f64, G, N, M>, eqtrack_controller::Error> {
        Reference::new(
            Self::configuration::<N>(&self.reference),
            SVector::from_row_slice(&self.reference.velocity),
            SMatrix::from_row_slice(&self.model_inertia),
            self.feedforward()?,
            self.control_period,
            self.reference_substeps,
        )
    }

    /// The path of a waypoint or set-point scenario (`None` for a feedforward series).
    pub fn path<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Option<Result<GroupPath<f64, G, N, M>, eqtrack_controller::Error>> {
        self.path.as_ref().map(build_path::<G, N, M>)
    }

    /// The desired trajectory, whichever its kind: the feedforward series integrated, or the
    /// path through waypoints (a set-point) stepped at the control period.
    pub fn reference_source<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Source<f64, G, N, M>, eqtrack_controller::Error> {
        Ok(match self.path::<G, N, M>() {
            None => Source::Series(self.reference_generator()?),
            Some(path) => Source::Path(PathReference::new(
                path?,
                SMatrix::from_row_slice(&self.model_inertia),
                self.control_period,
            )?),
        })
    }

    /// n×n configuration from a rotation vector and a position (ignored on SO(3)).
    pub fn pose<const N: usize>(rotation: [f64; 3], position: [f64; 3]) -> SMatrix<f64, N, N> {
        Self::configuration::<N>(&StateSpec {
            rotation,
            position,
            velocity: Vec::new(),
        })
    }

    /// The plant body at its initial state (true inertia, any added mass included).
    pub fn plant_body<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<RigidBody<f64, G, N, M>, eqtrack_controller::Error> {
        RigidBody::new(
            SMatrix::from_row_slice(&self.total_inertia()),
            Self::configuration::<N>(&self.initial),
            SVector::from_row_slice(&self.initial.velocity),
        )
    }

    /// A 64-bit fingerprint (FNV-1a, never 0) of what the controller takes from the scenario:
    /// the group, the control period and reference substeps, the model inertia, `K`, `K_d`,
    /// the torque limit, the reference's initial state and its feedforward. Not the law (a
    /// controller may override it), the duration, the name, nor the plant's own initial state,
    /// inertia or disturbances. The error frame when it is not `world`, the
    /// disturbance-rejection terms when there are any. Two processes of a pair compare it on their first message
    /// (docs/architecture.md, "Configuration identity").
    pub fn fingerprint(&self) -> u64 {
        let mut h = Fnv(0xcbf2_9ce4_8422_2325);
        h.bytes(self.group.name().as_bytes());
        h.f64s(&[self.control_period, self.reference_substeps as f64]);
        for part in [&self.model_inertia, &self.kp, &self.kd] {
            h.f64s(&[part.len() as f64]);
            h.f64s(part);
        }
        match &self.torque_limit {
            Some(l) => h.f64s(l),
            None => h.bytes(b"no limit"),
        }
        h.f64s(&self.reference.rotation);
        h.f64s(&self.reference.position);
        h.f64s(&self.reference.velocity);
        for axis in &self.feedforward {
            h.f64s(&[axis.offset, axis.terms.len() as f64]);
            for t in &axis.terms {
                h.f64s(&[t.amplitude, t.frequency, t.phase]);
            }
        }
        if let Some(p) = &self.path {
            h.f64s(&[p.times.len() as f64]);
            h.f64s(&p.times);
            for pose in &p.poses {
                h.f64s(&pose.rotation);
                h.f64s(&pose.position);
            }
            // only for a through-path, so stop paths keep their fingerprints
            if p.kind == PathKind::Through {
                h.bytes(b"through");
                for v in &p.velocities {
                    match v {
                        Some(v) => h.f64s(v),
                        None => h.bytes(b"chosen"),
                    }
                }
            }
        }
        self.fingerprint_controller_terms(&mut h);
        // only when present, so scenarios without one keep their fingerprints
        if let Some(v) = &self.vehicle {
            h.bytes(b"vehicle");
            let r = v.restoring();
            h.f64s(&[r.weight, r.buoyancy, r.centre.x, r.centre.y, r.centre.z]);
            h.f64s(&[v.actuator_rate_limit, v.actuators.len() as f64]);
            for a in &v.actuators {
                h.f64s(&a.position);
                h.f64s(&a.axis);
                h.f64s(&[a.torque_per_thrust, a.min, a.max]);
            }
            h.f64s(&v.weights);
            h.f64s(&v.preferred);
            h.bytes(match v.priority {
                eqtrack_allocation::Priority::Torque => b"torque first",
                eqtrack_allocation::Priority::None => b"no priority",
                eqtrack_allocation::Priority::Tilt => b"tilt first",
            });
            for f in v.failures.iter().filter(|f| f.reconfigure) {
                h.f64s(&[f.actuator as f64, f.t, f.value]);
                // a told loss of effectiveness is newer than the fingerprint: only it adds bytes
                if let crate::vehicle::FailureKind::Effectiveness { factor } = f.kind {
                    h.bytes(b"effectiveness");
                    h.f64s(&[factor]);
                }
            }
            // only when not the default, so scenarios from before it keep their fingerprints
            if v.budget != eqtrack_allocation::DEFAULT_BUDGET {
                h.bytes(b"allocation budget");
                h.f64s(&[f64::from(v.budget)]);
            }
            self.fingerprint_wheels(&mut h);
            self.fingerprint_fault_detection(&mut h);
        }
        self.fingerprint_failsafe(&mut h);
        h.0.max(1)
    }

    /// [`Scenario::fingerprint`]'s part for `[failsafe]`.
    fn fingerprint_failsafe(&self, h: &mut Fnv) {
        // only when on, so scenarios without it keep their fingerprints
        if let Some(f) = &self.failsafe {
            h.bytes(b"failsafe");
            for a in f.actions {
                h.bytes(a.map_or("none", failsafe::Action::name).as_bytes());
            }
            let limit = |x: Option<f64>| x.unwrap_or(-1.0);
            h.f64s(&[
                f.descend_rate,
                f.ascend_rate,
                limit(f.tracking_limit_attitude),
                limit(f.tracking_limit_position),
                f.clear_time,
            ]);
        }
    }

    /// [`Scenario::fingerprint`]'s part for `[fault_detection]`.
    /// The reaction wheels the controller allocates to and their momentum management: only
    /// when there are some, so scenarios without keep their fingerprints.
    fn fingerprint_wheels(&self, h: &mut Fnv) {
        let Some(v) = self.vehicle.as_ref().filter(|v| !v.wheels.is_empty()) else {
            return;
        };
        h.bytes(b"reaction wheels");
        for w in &v.wheels {
            h.f64s(&w.axis);
            h.f64s(&[w.inertia, w.max_torque, w.max_speed]);
        }
        if let Some(m) = &v.momentum {
            h.bytes(b"momentum management");
            h.f64s(&[m.null_gain, m.dump_threshold, m.dump_gain]);
            h.f64s(&m.bias);
        }
    }

    fn fingerprint_fault_detection(&self, h: &mut Fnv) {
        // only when on, so scenarios without it keep their fingerprints
        if let Some(f) = &self.fault_detection {
            h.bytes(b"fault detection");
            h.f64s(&[
                f.window,
                f.false_alarm_rate,
                f.warmup,
                f.calibration,
                f.memory,
                f.floor,
                f.confirm,
                f.unexplained,
                f.ambiguity,
                f.model_error,
            ]);
        }
    }

    /// [`Scenario::fingerprint`]'s part for the controller's error frame and its
    /// disturbance-rejection terms, each hashed only when it is not what a scenario from
    /// before it meant (the world frame, no term), so older scenarios and logs keep their
    /// fingerprints.
    fn fingerprint_controller_terms(&self, h: &mut Fnv) {
        // only when not the papers' world frame, so logs written before the key existed
        // (which flew the world frame) keep their fingerprints
        if self.error_frame != ErrorFrame::World {
            h.bytes(b"error frame ");
            h.bytes(self.error_frame.name().as_bytes());
        }
        // only when present, so scenarios without them keep their fingerprints
        if let Some(o) = &self.rejection.observer {
            h.bytes(b"observer");
            h.bytes(o.frame.name().as_bytes());
            h.f64s(&o.gain);
            if let Some(l) = &o.limit {
                h.f64s(l);
            }
        }
        if let Some(i) = &self.rejection.integral {
            h.bytes(if i.anti_windup {
                b"integral"
            } else {
                b"wound-up"
            });
            for part in [&i.ki, &i.c] {
                h.f64s(part);
            }
            if let Some(l) = &i.limit {
                h.f64s(l);
            }
        }
    }

    /// The disturbance as a vector.
    pub fn disturbance_vector<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_row_slice(&self.disturbance)
    }
}

/// FNV-1a, 64 bits.
struct Fnv(u64);

impl Fnv {
    fn bytes(&mut self, b: &[u8]) {
        for x in b {
            self.0 = (self.0 ^ u64::from(*x)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn f64s(&mut self, xs: &[f64]) {
        for x in xs {
            self.bytes(&x.to_bits().to_le_bytes());
        }
    }
}
