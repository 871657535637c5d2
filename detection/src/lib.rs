//! Actuator failures found, not announced (docs/maths.md, "Failure detection"): a detector
//! in the controller's cycle that notices an actuator has failed, finds which one, estimates
//! how (dead, stuck at a value, or weak by a factor) and tells the allocator: in the same
//! cycle, or over the cycles after where the tell reweights it (a weak actuator). The
//! windows' sums run, the test whitens with a pair renewed a step at a time, the
//! change point of the actuator about to be named is prepared in the entries that confirm
//! it, and taking a failure's shortfalls out of the window waits for the cycles after its
//! naming.
//!
//! * The residual: each period's momentum balance, `w = Δμ/h − ½(ad*μ terms) − B ū − ½(the
//!   environment's wrench at both ends)`, with the actuators' lag modelled (`ū` the mean
//!   output over the period) and the wrench the controller believes it applied. Healthy, `w`
//!   is what the model does not explain (wind, model error, noise); a failed actuator `j` adds
//!   `b_j (u_j,actual − ū_j)`.
//! * The test: the mean of `w` over the last window against the window before it, turned
//!   into body axes and whitened by its spread learned there in nominal flight, projected on
//!   each actuator's column: a bank of
//!   one hypothesis per actuator. An alarm is the best hypothesis above the χ²₁ threshold of
//!   the stated false-alarm rate ([`threshold`]) with what it leaves unexplained below the
//!   χ²_{K−1} isolation gate, so that a change no single actuator explains (a gust) is not
//!   taken for a failure, and ahead of the runner-up by a margin, so that of two actuators
//!   whose columns differ little the wrong one is seldom named.
//! * The kind: from the per-period shortfalls along the isolated column since the change,
//!   the least penalised (BIC) of "dead", "stuck at `v`" and "weak by `k`".
//!
//! `no_std`, no `alloc`; generic over the scalar and the wrench dimension `K` (3 on SO(3), 6
//! on SE(3)).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod threshold;

use eqtrack_allocation::{Commands, MAX_ACTUATORS, Reweighting, VehicleControl};
use eqtrack_controller::Real;
use eqtrack_controller::disturbance::rotate_blocks;
use eqtrack_controller::group::BuiltinGroup;
use nalgebra::{Matrix3, SMatrix, SVector};

/// The most periods the detector keeps: two windows.
pub const CAPACITY: usize = 64;

/// How a detected actuator failed, as estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind<T> {
    /// No output.
    Dead,
    /// Output held at a value, whatever its command.
    Stuck(T),
    /// Output a factor (in (0, 1)) of what it should be.
    Weak(T),
}

impl<T> Kind<T> {
    /// `"dead"`, `"stuck"` or `"effectiveness"`: the scenario's names of the kinds.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Dead => "dead",
            Kind::Stuck(_) => "stuck",
            Kind::Weak(_) => "effectiveness",
        }
    }
}

impl<T: Copy + Default> Kind<T> {
    /// The kind's code on the wire: 1 dead, 2 stuck, 3 effectiveness (0 is left for none).
    pub fn code(&self) -> u32 {
        match self {
            Kind::Dead => 1,
            Kind::Stuck(_) => 2,
            Kind::Weak(_) => 3,
        }
    }

    /// The estimate the kind carries: the stuck value, the factor, or the default (zero)
    /// when dead.
    pub fn value(&self) -> T {
        match self {
            Kind::Dead => T::default(),
            Kind::Stuck(v) | Kind::Weak(v) => *v,
        }
    }

    /// The kind of wire code `code` with estimate `value` ([`Kind::code`], [`Kind::value`];
    /// `None`: not a kind's code).
    pub fn from_code(code: u32, value: T) -> Option<Self> {
        match code {
            1 => Some(Kind::Dead),
            2 => Some(Kind::Stuck(value)),
            3 => Some(Kind::Weak(value)),
            _ => None,
        }
    }
}

impl<T: Real> Kind<T> {
    /// Tells `control` that actuator `j` is now this, forgetting what it was told of it
    /// before: held at 0 or at the stuck value, or its column scaled by the factor.
    pub fn tell<const K: usize>(&self, j: usize, control: &mut VehicleControl<T, K>) {
        match *self {
            // its bounds released and its factor told at once: the allocator reweighted once
            Kind::Weak(k) => {
                control.release(j);
                control.weaken(j, k)
            }
            Kind::Dead | Kind::Stuck(_) => {
                let held = if let Kind::Stuck(v) = *self {
                    v
                } else {
                    T::zero()
                };
                // what `heal` then `fail` tell, without their overlap: `fail` sets both bounds,
                // and a factor is told back to 1 only if it is not (an actuator past the
                // vehicle's is ignored, as `weaken` and `fail` ignore it)
                if control.factors().get(j).is_some_and(|f| *f != T::one()) {
                    control.weaken(j, T::one());
                }
                control.fail(j, held)
            }
        }
    }
}

impl<T: Real> Kind<T> {
    /// The factor the allocator is told for actuator `j` when it is this: the estimate when
    /// weak, 1 otherwise (held, its column healthy again).
    fn factor(&self) -> T {
        match *self {
            Kind::Weak(k) => k,
            Kind::Dead | Kind::Stuck(_) => T::one(),
        }
    }

    /// [`Kind::tell`] with the factor's reweighting `r` (begun for this tell and formed over
    /// the cycles before) put in force in place of `weaken`: the same vehicle, bit for bit.
    fn tell_reweighted<const K: usize>(
        &self,
        j: usize,
        control: &mut VehicleControl<T, K>,
        r: &mut Reweighting<T, K>,
    ) {
        match *self {
            Kind::Weak(_) => {
                control.release(j);
                control.reweight(r);
            }
            Kind::Dead => {
                control.reweight(r);
                control.fail(j, T::zero());
            }
            Kind::Stuck(v) => {
                control.reweight(r);
                control.fail(j, v);
            }
        }
    }
}

/// A detection whose tell moves the allocator's factor of its actuator, told over the
/// cycles after its finding (docs/maths.md, "Failure detection", *A weak actuator told over
/// cycles*): the reweighting begun in the first, a few columns of its updates in each, and
/// in force, the detection told and reported, in the cycle after the last.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Telling<T, const K: usize> {
    detection: Detection<T>,
    /// The control periods since its finding (those of a gap included).
    waited: usize,
    reweighting: Option<Reweighting<T, K>>,
}

/// The columns of a reweighting's rank-one updates formed in one cycle ([`Detector::step`]).
const COLUMNS: usize = 2;

/// One detection: the actuator, its kind, the test's statistic and when the change began.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection<T> {
    /// The actuator (0-based).
    pub actuator: usize,
    /// How it failed.
    pub kind: Kind<T>,
    /// The best hypothesis's statistic (χ²₁ under no failure).
    pub statistic: T,
    /// How many control periods before this one the change is estimated to have begun (a
    /// refined detection: the periods since its kind was fitted again, which a weak kind's
    /// tell over cycles makes more than 0).
    pub since: usize,
    /// Whether this refines an earlier detection of the same actuator: the kind estimated
    /// again after watching it for a window once the allocator was told.
    pub refined: bool,
}

/// An actuator watched after its detection: its shortfalls measured against the baseline
/// of the detection, for a window, before its kind is estimated again.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Watch<T, const K: usize> {
    actuator: usize,
    left: usize,
    /// The older window's mean at the detection (world axes).
    baseline: SVector<T, K>,
    /// The shortfall's weights in body axes, `(b_j ⊘ s²) / |b̃_j|²`, from the spread of the
    /// detection.
    weights: SVector<T, K>,
    kind: Kind<T>,
}

/// The last detection's change, whose shortfalls are taken out of the window over the
/// cycles after its naming, half a window of entries a cycle
/// (docs/maths.md, "Failure detection", paragraph "After the naming").
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    /// The entries kept since the naming (the ages of the entries it reads grow by one each),
    /// the entries whose shortfalls are taken out so far, and the change's entries.
    shift: usize,
    done: usize,
    span: usize,
}

impl Pending {
    fn zero() -> Self {
        Pending {
            shift: 0,
            done: 0,
            span: 0,
        }
    }
}

/// The change point of the actuator leading the tests, prepared over the entries before it
/// is named (docs/maths.md, "Failure detection", paragraph "The kind, prepared ahead"): its
/// shortfall's weights and, in [`Detector::along`], its weights and column in world axes at
/// the attitude of its first lead; each entry of the window the naming will read is projected
/// on the weights a few at a time, so that the naming's cycle only sums them.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Prep<T, const K: usize> {
    /// The shortfall's weights in body axes ([`Watch::weights`]).
    weights: SVector<T, K>,
    /// The slot of the next entry to project, and the tests left to project them in before
    /// the naming's entry.
    next: usize,
    cycles: usize,
    /// The attitude of the first lead, and whether the column has been turned into world
    /// axes at it yet (in the first entry that projects, or else at the naming: the entry of
    /// the first lead carries a test, and the naming the change point).
    rotation: Matrix3<T>,
    turned: bool,
    /// The actuator.
    actuator: usize,
}

impl<T: Real, const K: usize> Prep<T, K> {
    fn zero() -> Self {
        Prep {
            weights: SVector::zeros(),
            next: 0,
            cycles: 1,
            rotation: Matrix3::identity(),
            turned: false,
            actuator: 0,
        }
    }
}

/// The whitening the test uses: `s⁻²` per body axis and each column's `|b̃_j|²`, renewed
/// one step a test into `next` and `norms_next` and then taken in whole.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Whitening<T, const K: usize> {
    inverse: SVector<T, K>,
    norms: [T; MAX_ACTUATORS],
    next: SVector<T, K>,
    norms_next: [T; MAX_ACTUATORS],
    step: usize,
    /// Whether a whole pair has been taken, and the steps of one (the actuators and one).
    ready: bool,
    steps: T,
}

impl<T: Real, const K: usize> Whitening<T, K> {
    fn zero() -> Self {
        Whitening {
            inverse: SVector::zeros(),
            norms: [T::zero(); MAX_ACTUATORS],
            next: SVector::zeros(),
            norms_next: [T::zero(); MAX_ACTUATORS],
            step: 0,
            ready: false,
            steps: T::zero(),
        }
    }
}

/// The two windows' running sums of the residual (docs/maths.md, "Failure detection", "Two
/// windows"): each new entry is added to the recent one and the entry it pushes on moves to
/// the older one. Every `W` entries both are set afresh from the sums of the last two blocks
/// of `W` entries, so that rounding never gathers over more than `3W` additions.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Windows<T, const K: usize> {
    recent: SVector<T, K>,
    older: SVector<T, K>,
    /// The block being summed, its entries so far, and the block before it.
    block: SVector<T, K>,
    filled: usize,
    before: SVector<T, K>,
}

impl<T: Real, const K: usize> Windows<T, K> {
    fn zero() -> Self {
        Windows {
            recent: SVector::zeros(),
            older: SVector::zeros(),
            block: SVector::zeros(),
            filled: 0,
            before: SVector::zeros(),
        }
    }
}

/// Why a detector's settings are refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigError {
    /// `window` is not 1 to `CAPACITY / 2` entries.
    Window,
    /// `calibration` is shorter than two windows.
    Calibration,
    /// `confirm` is not 1 to `window` entries.
    Confirm,
    /// A threshold, the memory, the floor, the period, the decimation, the relative error or
    /// the lag is not finite and positive (the lag and the relative error may be 0): the
    /// field's name.
    Value(&'static str),
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Window => write!(f, "the window must be 1 to {} entries", CAPACITY / 2),
            ConfigError::Calibration => {
                write!(f, "the calibration must last at least two windows")
            }
            ConfigError::Confirm => write!(f, "the confirmation must be 1 to `window` entries"),
            ConfigError::Value(what) => write!(f, "`{what}` must be finite and positive"),
        }
    }
}

/// The detector's settings (docs/maths.md, "Failure detection").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config<T, const K: usize> {
    /// Control periods averaged into each kept entry (at least 1): a fast loop keeps a window
    /// of the same length in as many entries as a slower one.
    pub decimation: usize,
    /// Entries per window (1 to `CAPACITY / 2`).
    pub window: usize,
    /// The χ²₁ threshold of the best hypothesis ([`threshold::chi2_upper`]).
    pub threshold: T,
    /// The χ²_{K−1} gate on what the best hypothesis leaves unexplained.
    pub isolation: T,
    /// The model's relative error, squared (`ε²`): the unexplained part may also be up to
    /// `ε²` of the whole change, since the model's errors grow with what the vehicle does
    /// (a thruster that sticks at full thrust throws the vehicle about, and the residual's
    /// integration is then less exact).
    pub relative: T,
    /// The least lead of the best hypothesis's statistic over the runner-up's (twice their
    /// log-likelihood ratio; a χ²₁ quantile of the chance of isolating the wrong actuator).
    pub margin: T,
    /// Consecutive entries the same actuator must lead before it is named (at least 1): it
    /// passes every gate in all but the last, which names it without a test (with 1, its one
    /// test names it). A change that no single actuator explains shows as such only once
    /// enough of it has entered the window.
    pub confirm: usize,
    /// Entries at the start in which the detector neither learns nor tests: the estimator's
    /// and the controller's own start, whose transients are not the flight's spread.
    pub warmup: usize,
    /// Entries of nominal flight the spread is learned over (after the warm-up) before the
    /// first test.
    pub calibration: usize,
    /// The weight `λ` of each new period in the spread's running estimate afterwards (`h`
    /// over the memory's time).
    pub memory: T,
    /// The least spread of the residual per axis (absolute, wrench units).
    pub floor: SVector<T, K>,
    /// The least shortfall resolved per actuator (command units), for the kind's fit.
    pub resolution: Commands<T>,
    /// The model's inertia `I` (with any added mass).
    pub inertia: SMatrix<T, K, K>,
    /// Fossen's linear damping (diagonal).
    pub damping_linear: SVector<T, K>,
    /// Fossen's quadratic damping (diagonal).
    pub damping_quadratic: SVector<T, K>,
    /// The control period `h` (s).
    pub period: T,
    /// The actuators' lag `T` (s; 0: none).
    pub time_constant: T,
}

/// What the detector keeps of each period.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry<T, const K: usize> {
    /// The period's residual `w` (wrench).
    w: SVector<T, K>,
    /// Each actuator's mean output over the period were it healthy: its commands through
    /// the lag (the regressor of a loss of effectiveness).
    u: Commands<T>,
    /// Each actuator's mean thrust over the period as the detector then believed it, in
    /// healthy units (the told factor times the believed output: a held value or `u`).
    p: Commands<T>,
}

impl<T: Real, const K: usize> Entry<T, K> {
    fn zero() -> Self {
        Entry {
            w: SVector::zeros(),
            u: Commands::zeros(),
            p: Commands::zeros(),
        }
    }
}

/// Sums over the periods attributed to one failed actuator: the count, `Σy`, `Σy²`, `Σuy`
/// and `Σu²` of its actual thrust `y` against its healthy output `u`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sums<T> {
    /// The entries, as a count and as a number.
    count: usize,
    n: T,
    y: T,
    yy: T,
    uy: T,
    uu: T,
}

impl<T: Real> Sums<T> {
    fn zero() -> Self {
        Sums {
            count: 0,
            n: T::zero(),
            y: T::zero(),
            yy: T::zero(),
            uy: T::zero(),
            uu: T::zero(),
        }
    }

    fn add(&mut self, u: T, y: T) {
        self.count += 1;
        self.n += T::one();
        self.y += y;
        self.yy += y * y;
        self.uy += u * y;
        self.uu += u * u;
    }
}

/// What the detector kept of the last state: the momentum, and half the gyroscopic and
/// environment's wrench, `½(ad_Vᵀμ + τ_env)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Previous<T, const K: usize> {
    mu: SVector<T, K>,
    half: SVector<T, K>,
}

/// The last test's figures, for the record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Statistic<T> {
    /// The best hypothesis's actuator.
    pub actuator: usize,
    /// Its statistic (χ²₁ under no failure).
    pub best: T,
    /// The runner-up's statistic.
    pub second: T,
    /// The whole whitened change, `|d̃|²` (χ²_K under no failure).
    pub total: T,
    /// Whether the detector was testing (calibrated, windows full).
    pub testing: bool,
}

/// The detector between cycles: the actuators' lag model, the last state, the ring of
/// periods, the learned spread and the actuators found failed. Allocation-free.
#[derive(Debug, Clone, PartialEq)]
// in this order, the fields every cycle reads first, within the reach of a load's offset on
// a Cortex-M4F (1 KiB), and the ring last
#[repr(C)]
pub struct Detector<T, const K: usize> {
    /// `e^{−h/T}` and `(T/h)(1 − e^{−h/T})`: the lag's output at the end of a period and its
    /// mean over it, as weights of the start (0 and 0 without lag).
    decay: T,
    mean: T,
    /// The window's and the calibration's lengths as numbers (the counts a cycle divides by
    /// are kept as numbers: turning an integer into `f32` through `f64` is a library call on a
    /// single-precision FPU).
    window_n: T,
    calibration_n: T,
    /// Whether the inertia is diagonal (its momentum then by its diagonal).
    diagonal: bool,
    /// Whether a command has been held (the lag model has started).
    held: bool,
    /// Periods still to pass without a residual after a gap, while the lag model settles.
    settling: usize,
    /// The actuators whose healthy columns are formed (0: not yet).
    formed: usize,
    /// The allocator's count of tells when `stuck` was read ([`VehicleControl::told`]).
    told: Option<u32>,
    /// The ring's next slot and its entries kept, and the periods summed towards the next
    /// entry.
    head: usize,
    len: usize,
    periods: usize,
    /// Entries of the warm-up passed.
    warmed: usize,
    /// The entries the spread was learned over in the calibration.
    learned: T,
    /// The queue's oldest slot, and how many wait.
    first_queued: usize,
    queued: usize,
    /// Whether a detection's shortfalls are still being taken out of the window.
    pending: bool,
    /// Whether a detection is being told over cycles: `staged` is some (kept here too, among
    /// the fields every cycle reads, where `staged` lies past the first KiB).
    telling: bool,
    /// The actuator passing every gate and for how many periods in a row.
    streak: (usize, usize),
    /// The actuator the next entry names, and its last test's statistic: it passed the tests
    /// of `confirm − 1` entries in a row, and the entry after them names it without a test.
    armed: Option<(usize, T)>,
    /// The leading actuator's change point, prepared ahead.
    prep: Prep<T, K>,
    /// Alarms so far: periods whose best statistic crossed the threshold after one that did
    /// not (isolated or not).
    alarms: u32,
    alarmed: bool,
    /// The attitude of the last state: residuals are kept in world axes, where a steady wind
    /// or current is constant however the body turns.
    rotation: Matrix3<T>,
    /// What was kept of the last state.
    previous: Option<Previous<T, K>>,
    /// The two windows' running sums.
    windows: Windows<T, K>,
    /// The whitening the test uses, and the one being renewed.
    whitening: Whitening<T, K>,
    /// The learned spread (variance per body axis).
    variance: SVector<T, K>,
    /// The floor's square per axis.
    floor2: SVector<T, K>,
    /// The healthy output at the start of the held period, and the held command.
    output: Commands<T>,
    command: Commands<T>,
    /// The value each actuator the allocator holds (found dead or stuck, or told so by the
    /// scenario) was held at over the period that runs: the allocator's locked bounds when
    /// the last cycle ended. A failed actuator's thrust jumps to its value, where a command
    /// would ramp through the lag.
    stuck: [Option<T>; MAX_ACTUATORS],
    /// The last detection's change.
    job: Pending,
    /// The weights `g` of the leading (or named) actuator in world axes, at the attitude of
    /// its first lead, and its column there once turned ([`Detector::turn`]; until then, the
    /// last actuator's).
    along: [SVector<T, K>; 2],
    /// The last test's figures.
    last: Statistic<T>,
    /// The actuator watched after its detection.
    watch: Option<Watch<T, K>>,
    /// A watch that ended (or that a detection cut short), its kind fitted again in the next
    /// entry, and a detection being completed over the entries after its finding.
    ending: Option<Watch<T, K>>,
    /// The actuators found failed.
    failed: [bool; MAX_ACTUATORS],
    /// Detections not reported yet (a refinement and a detection in the same entry, or one
    /// watch cut short by another detection): the next cycles report them, oldest first.
    queue: [Option<Detection<T>>; 3],
    /// The settings.
    config: Config<T, K>,
    /// The BIC's factors for each count of entries ([`Detector::fit`]).
    penalties: [(T, T); PENALTIES],
    /// Each actuator's healthy column in body axes and its entries' squares, formed at the
    /// first period (`formed` actuators; 0: not yet).
    columns: [SVector<T, K>; MAX_ACTUATORS],
    squares: [SVector<T, K>; MAX_ACTUATORS],
    /// What each failed actuator's periods have shown so far.
    sums: [Sums<T>; MAX_ACTUATORS],
    /// The shortfalls the change point measured, newest first (those of the last
    /// detection's change are taken out of the window after its naming).
    shorts: [T; CAPACITY / 2],
    /// Each entry's residual projected on the leading actuator's weights in world axes,
    /// `gᵀw`, by slot (those of the window the naming will read).
    proj: [T; CAPACITY],
    /// The periods summed towards the next entry, and the period being summed.
    accumulated: Entry<T, K>,
    scratch: Entry<T, K>,
    /// The entries kept, two windows at most.
    ring: [Entry<T, K>; CAPACITY],
    /// Each actuator's command bounds before any failure, formed with the columns (read only
    /// when an actuator's kind is fitted).
    ranges: [(T, T); MAX_ACTUATORS],
    /// The detection being told over cycles, while `telling`.
    staged: Option<Telling<T, K>>,
}

impl<T: Real, const K: usize> Detector<T, K> {
    /// A detector with settings `config`, checked.
    pub fn new(config: Config<T, K>) -> Result<Self, ConfigError> {
        Self::check(&config)?;
        let (decay, mean) = if config.time_constant > T::zero() {
            let d = (-config.period / config.time_constant).exp();
            (d, config.time_constant / config.period * (T::one() - d))
        } else {
            (T::zero(), T::zero())
        };
        Ok(Detector {
            config,
            decay,
            mean,
            floor2: config.floor.component_mul(&config.floor),
            penalties: penalty_table(),
            window_n: eqtrack_controller::real(config.window as f64),
            diagonal: config.inertia == SMatrix::from_diagonal(&config.inertia.diagonal()),
            calibration_n: eqtrack_controller::real(config.calibration as f64),
            output: Commands::zeros(),
            command: Commands::zeros(),
            held: false,
            settling: 0,
            stuck: [None; MAX_ACTUATORS],
            told: None,
            columns: [SVector::zeros(); MAX_ACTUATORS],
            ranges: [(T::zero(), T::zero()); MAX_ACTUATORS],
            squares: [SVector::zeros(); MAX_ACTUATORS],
            formed: 0,
            sums: [Sums::zero(); MAX_ACTUATORS],
            watch: None,
            ending: None,
            pending: false,
            telling: false,
            staged: None,
            job: Pending::zero(),
            shorts: [T::zero(); CAPACITY / 2],
            along: [SVector::zeros(); 2],
            queue: [None; 3],
            first_queued: 0,
            queued: 0,
            previous: None,
            rotation: Matrix3::identity(),
            ring: [Entry::zero(); CAPACITY],
            windows: Windows::zero(),
            accumulated: Entry::zero(),
            scratch: Entry::zero(),
            periods: 0,
            head: 0,
            len: 0,
            variance: SVector::zeros(),
            warmed: 0,
            learned: T::zero(),
            whitening: Whitening::zero(),
            failed: [false; MAX_ACTUATORS],
            last: Statistic {
                actuator: 0,
                best: T::zero(),
                second: T::zero(),
                total: T::zero(),
                testing: false,
            },
            streak: (0, 0),
            armed: None,
            prep: Prep::zero(),
            proj: [T::zero(); CAPACITY],
            alarms: 0,
            alarmed: false,
        })
    }

    /// Refuses settings out of their ranges ([`ConfigError`]).
    fn check(config: &Config<T, K>) -> Result<(), ConfigError> {
        let positive = |x: T| x.is_finite() && x > T::zero();
        if config.decimation == 0 {
            return Err(ConfigError::Value("decimation"));
        }
        if config.window == 0 || 2 * config.window > CAPACITY {
            return Err(ConfigError::Window);
        }
        if config.calibration < 2 * config.window {
            return Err(ConfigError::Calibration);
        }
        if config.confirm == 0 || config.confirm > config.window {
            return Err(ConfigError::Confirm);
        }
        for (what, x) in [
            ("threshold", config.threshold),
            ("isolation", config.isolation),
            ("margin", config.margin),
            ("memory", config.memory),
            ("period", config.period),
        ] {
            if !positive(x) {
                return Err(ConfigError::Value(what));
            }
        }
        if config.memory > T::one() {
            return Err(ConfigError::Value("memory"));
        }
        if !(config.relative.is_finite() && config.relative >= T::zero()) {
            return Err(ConfigError::Value("relative"));
        }
        if !config.floor.iter().all(|x| positive(*x)) {
            return Err(ConfigError::Value("floor"));
        }
        if !(config.time_constant.is_finite() && config.time_constant >= T::zero()) {
            return Err(ConfigError::Value("time_constant"));
        }
        Ok(())
    }

    /// Starts afresh with the same settings, in place: afterwards it equals
    /// `Detector::new(*self.config())`. A controller that starts a new run resets its
    /// detector so, without a temporary of the detector's size on its stack (a
    /// microcontroller's is small, and the ring alone is 64 entries).
    pub fn restart(&mut self) {
        self.output = Commands::zeros();
        self.command = Commands::zeros();
        self.held = false;
        self.settling = 0;
        self.stuck = [None; MAX_ACTUATORS];
        self.told = None;
        self.columns = [SVector::zeros(); MAX_ACTUATORS];
        self.ranges = [(T::zero(), T::zero()); MAX_ACTUATORS];
        self.squares = [SVector::zeros(); MAX_ACTUATORS];
        self.formed = 0;
        self.sums = [Sums::zero(); MAX_ACTUATORS];
        self.watch = None;
        self.ending = None;
        self.pending = false;
        self.telling = false;
        self.staged = None;
        self.job = Pending::zero();
        self.shorts = [T::zero(); CAPACITY / 2];
        self.along = [SVector::zeros(); 2];
        self.queue = [None; 3];
        self.first_queued = 0;
        self.queued = 0;
        self.previous = None;
        self.rotation = Matrix3::identity();
        for e in &mut self.ring {
            *e = Entry::zero();
        }
        self.windows = Windows::zero();
        self.accumulated = Entry::zero();
        self.scratch = Entry::zero();
        self.periods = 0;
        self.head = 0;
        self.len = 0;
        self.variance = SVector::zeros();
        self.warmed = 0;
        self.learned = T::zero();
        self.whitening = Whitening::zero();
        self.failed = [false; MAX_ACTUATORS];
        self.last = Statistic {
            actuator: 0,
            best: T::zero(),
            second: T::zero(),
            total: T::zero(),
            testing: false,
        };
        self.streak = (0, 0);
        self.armed = None;
        self.prep = Prep::zero();
        self.proj = [T::zero(); CAPACITY];
        self.alarms = 0;
        self.alarmed = false;
    }

    /// The settings.
    pub fn config(&self) -> &Config<T, K> {
        &self.config
    }

    /// Forgets the last state: the controller did not see the one before this cycle's (a
    /// missed or late state), or the plant did not apply its last command (held, or safe
    /// mode), so the thrust of the period is not what the detector believes. No residual is
    /// taken over it, nor over the next five time constants of the actuators' lag, while the
    /// lag model, which did not see what the plant applied, settles on the commands again
    /// (to within e⁻⁵, 0.7 %, of the difference). The windows, the spread learned and the findings stay. Before the first command
    /// there is nothing to forget.
    pub fn gap(&mut self) {
        self.previous = None;
        if self.held && self.config.time_constant > T::zero() {
            let lag =
                eqtrack_controller::real::<T>(5.0) * self.config.time_constant / self.config.period;
            self.settling = nalgebra::try_convert::<T, f64>(lag.ceil()).unwrap_or(0.0) as usize;
        }
    }

    /// The actuators found failed so far.
    pub fn failed(&self) -> &[bool; MAX_ACTUATORS] {
        &self.failed
    }

    /// The last test's figures.
    pub fn statistic(&self) -> &Statistic<T> {
        &self.last
    }

    /// The alarms so far: each time the best hypothesis's statistic crossed the threshold,
    /// whether or not an actuator was then isolated. In nominal flight their rate is at most
    /// the stated false-alarm rate.
    pub fn alarms(&self) -> u32 {
        self.alarms
    }

    /// The spread learned so far (the standard deviation's square per body axis, before the
    /// floor).
    pub fn variance(&self) -> &SVector<T, K> {
        &self.variance
    }

    /// The command the allocation answered this cycle, held over the next period: the
    /// actuators' lag model starts from it (the first command is also the output at once, as
    /// the plant's actuators do).
    pub fn commanded(&mut self, u_cmd: &Commands<T>) {
        self.command = *u_cmd;
        if !self.held || self.config.time_constant <= T::zero() {
            self.output = *u_cmd;
            self.held = true;
        }
    }

    /// One cycle before the allocation (docs/maths.md, "Failure detection"): the residual of
    /// the period that ended at this state (body velocity `v`, attitude `r`), the test, and on
    /// a detection the allocator told: a dead or stuck actuator held at its value at once
    /// ([`VehicleControl::fail`]), a weak one scaled over the cycles after, a step a cycle in
    /// place of the test ([`VehicleControl::reweighting`]; docs/maths.md, "Failure detection",
    /// *A weak actuator told over cycles*). A detection is returned in the cycle the allocator
    /// is told it (or the next ones, behind others). Allocation-free.
    pub fn observe<G: BuiltinGroup<N, K>, const N: usize>(
        &mut self,
        v: &SVector<T, K>,
        r: &Matrix3<T>,
        control: &mut VehicleControl<T, K>,
    ) -> Option<Detection<T>> {
        self.observe_wheeled::<G, N>(v, r, &[], control)
    }

    /// [`Detector::observe`] of a vehicle with reaction wheels turning at `speeds` (relative
    /// to the body, one per wheel of `control`; docs/maths.md, "Failure detection" and
    /// "Reaction wheels"): the body's momentum balance carries the wheels' momentum in its
    /// gyroscopic term, and a wheel's motor torque acts at once (no actuator lag).
    pub fn observe_wheeled<G: BuiltinGroup<N, K>, const N: usize>(
        &mut self,
        v: &SVector<T, K>,
        r: &Matrix3<T>,
        speeds: &[T],
        control: &mut VehicleControl<T, K>,
    ) -> Option<Detection<T>> {
        let found = self.period::<G, N>(v, r, speeds, control);
        // what the allocator holds over the next period: what this cycle told it, and any
        // failure the scenario told it of at this tick (the plant's actuator stuck from now)
        // (read again only when the bounds were told since: a detector paired with another
        // `VehicleControl` is restarted first)
        if self.told != Some(control.told()) {
            self.told = Some(control.told());
            let count = control.allocator().geometry().count();
            for (j, s) in self.stuck.iter_mut().enumerate().take(count) {
                *s = control.held(j);
            }
        }
        found
    }

    /// The healthy columns in body axes (the allocator's geometry, whatever was told), and
    /// their squares, and the commands' bounds before any failure.
    // called once, and kept out of the cycle's code
    #[inline(never)]
    fn form(&mut self, control: &VehicleControl<T, K>) {
        let geometry = control.allocator().geometry();
        let b = geometry.effectiveness();
        let (lo, hi) = control.nominal_bounds();
        for j in 0..geometry.count() {
            self.ranges[j] = (lo[j], hi[j]);
            self.columns[j] = b.column(j).into_owned();
            self.squares[j] = self.columns[j].component_mul(&self.columns[j]);
        }
        self.formed = geometry.count();
        self.whitening.steps = eqtrack_controller::real((self.formed + 1) as f64);
    }

    /// What the residual keeps of the state (body velocity `v`, attitude `r`): the momentum
    /// `I V` (a diagonal inertia by its diagonal: the same bits) and `½(ad_Vᵀμ + τ_env)`.
    fn momentum<G: BuiltinGroup<N, K>, const N: usize>(
        &self,
        v: &SVector<T, K>,
        r: &Matrix3<T>,
        speeds: &[T],
        control: &VehicleControl<T, K>,
    ) -> Previous<T, K> {
        let c = &self.config;
        let mu = if self.diagonal {
            c.inertia.diagonal().component_mul(v)
        } else {
            c.inertia * v
        };
        let gyro = G::ad_transpose_mul(v, &with_wheels(mu, v, speeds, control));
        let drag = -(c.damping_linear.component_mul(v)
            + c.damping_quadratic.component_mul(&v.abs().component_mul(v)));
        let half: T = eqtrack_controller::real(0.5);
        Previous {
            mu,
            half: (gyro + control.restoring(r) + drag) * half,
        }
    }

    /// The period in `scratch` added to the entry being summed; after `decimation` periods
    /// their mean is written in `slot`, watched, and the entry is complete (true).
    fn average(&mut self, slot: usize) -> bool {
        let (a, e) = (&mut self.accumulated, &self.scratch);
        a.w += e.w;
        a.u += e.u;
        a.p += e.p;
        self.periods += 1;
        if self.periods < self.config.decimation {
            return false;
        }
        let n: T = eqtrack_controller::real(self.periods as f64);
        self.leave();
        let a = &self.accumulated;
        self.ring[slot] = Entry {
            w: a.w / n,
            u: a.u / n,
            p: a.p / n,
        };
        self.accumulated = Entry::zero();
        self.periods = 0;
        self.watching(slot);
        true
    }

    /// [`Detector::observe`] but for what the allocator holds next.
    fn period<G: BuiltinGroup<N, K>, const N: usize>(
        &mut self,
        v: &SVector<T, K>,
        r: &Matrix3<T>,
        speeds: &[T],
        control: &mut VehicleControl<T, K>,
    ) -> Option<Detection<T>> {
        let count = control.allocator().geometry().count();
        if self.formed != count {
            self.form(control);
        }
        let now = self.momentum::<G, N>(v, r, speeds, control);
        let c = &self.config;
        self.rotation = *r;
        let seen = self.previous.is_some();
        let p = self.previous.get_or_insert(now);
        let (momentum, held_half) = (p.mu, p.half);
        *p = now;
        if !(seen && self.held) {
            self.idle();
            return self.next_report();
        }
        // a wheel's motor has no lag: its torque is the command held over the period
        let first = control.wheels().first();
        for j in first..first + control.wheels().wheels().len() {
            self.output[j] = self.command[j];
        }
        // the entry is built in its slot of the ring (one period an entry), or in the
        // accumulator; the slots past the vehicle's actuators stay zero
        let decimated = c.decimation > 1;
        let slot = self.head;
        let e = if decimated {
            &mut self.scratch
        } else {
            &mut self.ring[slot]
        };
        // the held period over the vehicle's actuators: the lag's mean output and its output
        // at the end; the thrust believed, a held value for an actuator held (found or told
        // stuck or dead), and `B ū`
        let b = control.allocator().geometry().effectiveness();
        let factors = control.factors();
        let mut thrust = SVector::<T, K>::zeros();
        for j in 0..count {
            let (out, cmd) = (self.output[j], self.command[j]);
            let u = cmd + (out - cmd) * self.mean;
            self.output[j] = cmd + (out - cmd) * self.decay;
            let believed = self.stuck[j].unwrap_or(u);
            e.u[j] = u;
            e.p[j] = believed * factors[j];
            thrust += b.column(j) * e.p[j];
        }
        if self.settling > 0 {
            self.settling -= 1;
            self.idle();
            return self.next_report();
        }
        let mut body = (now.mu - momentum) / c.period - held_half - now.half - thrust;
        if !decimated {
            // the watch in body axes, before the residual is turned (one turn fewer)
            self.watching_body(&mut body, slot);
            self.leave();
        }
        let e = if decimated {
            &mut self.scratch
        } else {
            &mut self.ring[slot]
        };
        e.w = rotate_blocks(r, &body);
        if decimated && !self.average(slot) {
            // between entries the work after a naming goes on, one step a period
            self.work(control);
            return self.next_report();
        }
        self.push();
        // one of: the naming of the actuator that led the tests before, a watch's end, a step
        // of completing a detection, or the test
        if let Some((j, t)) = self.armed.take() {
            self.last.testing = false;
            self.found(j, t, self.windows.older / self.window_n, control);
        } else if !self.work(control) {
            self.test(control);
        }
        self.next_report()
    }

    /// One step of the work after a naming, if there is any: a step of telling a detection
    /// over cycles, a watch's end (its kind fitted again), or a step of completing a
    /// detection. True if there was.
    fn work(&mut self, control: &mut VehicleControl<T, K>) -> bool {
        if self.telling {
            self.last.testing = false;
            self.step(control);
            true
        } else if let Some(watch) = self.ending.take() {
            self.last.testing = false;
            self.refine(&watch, control);
            true
        } else if self.pending {
            self.last.testing = false;
            self.take(self.config.window.div_ceil(2));
            self.pending = self.job.done < self.job.span;
            true
        } else {
            false
        }
    }

    /// Keeps `d` to report (a full queue drops the oldest: never more than three wait).
    fn report(&mut self, d: Detection<T>) {
        let n = self.queue.len();
        if self.queued == n {
            self.first_queued = (self.first_queued + 1) % n;
            self.queued -= 1;
        }
        self.queue[(self.first_queued + self.queued) % n] = Some(d);
        self.queued += 1;
    }

    /// The oldest detection not reported yet.
    fn next_report(&mut self) -> Option<Detection<T>> {
        if self.queued == 0 {
            return None;
        }
        let first = self.queue[self.first_queued].take();
        self.first_queued = (self.first_queued + 1) % self.queue.len();
        self.queued -= 1;
        first
    }

    /// The shortfall weights `g = blockdiag(R, R)(b_j ⊘ s²) / |b̃_j|²` in world axes at the
    /// last attitude, and actuator `j`'s healthy column there: an entry's shortfall along the
    /// column is `gᵀ(w − baseline)` (docs/maths.md, "Failure detection", "The kind").
    fn along(&self, j: usize, weights: &SVector<T, K>) -> (SVector<T, K>, SVector<T, K>) {
        (
            rotate_blocks(&self.rotation, weights),
            rotate_blocks(&self.rotation, &self.columns[j]),
        )
    }

    /// The watched actuator's shortfall in this period, added to its sums and taken out of
    /// the residual; after a window, its kind estimated again from all its sums and, if it
    /// changed, the allocator told again (a refined detection) in the entry after.
    fn watching(&mut self, slot: usize) {
        let Some(watch) = self.watch.as_ref() else {
            return;
        };
        let j = watch.actuator;
        let (g, column) = self.along(j, &watch.weights);
        let e = &mut self.ring[slot];
        let short = g.dot(&(e.w - watch.baseline));
        self.sums[j].add(e.u[j], e.p[j] + short);
        e.w -= column * short;
        self.watched();
    }

    /// [`Detector::watching`] of an entry of one period, on its residual `body` before it is
    /// turned into world axes: the shortfall `(b_j ⊘ s²)ᵀ(w_body − Rᵀ baseline) / |b̃_j|²` is
    /// the same, and the column taken out is the body's.
    fn watching_body(&mut self, body: &mut SVector<T, K>, slot: usize) {
        let Some(watch) = self.watch.as_ref() else {
            return;
        };
        let j = watch.actuator;
        let short = watch
            .weights
            .dot(&(*body - body_blocks(&self.rotation, &watch.baseline)));
        let e = &self.ring[slot];
        self.sums[j].add(e.u[j], e.p[j] + short);
        *body -= self.columns[j] * short;
        self.watched();
    }

    /// One more entry of the watch: at its end, the kind is fitted again in the next entry.
    fn watched(&mut self) {
        if let Some(watch) = self.watch.as_mut() {
            watch.left = watch.left.saturating_sub(1);
            // a detection still being completed has its kind told first; at the end, the
            // kind is fitted again in the next entry, in place of the test
            if watch.left == 0 && !self.pending {
                self.ending = self.watch.take();
            }
        }
    }

    /// The end of a watch: the kind fitted again over everything seen of the actuator and, if
    /// it changed, the allocator told again (a refined detection).
    fn refine(&mut self, watch: &Watch<T, K>, control: &mut VehicleControl<T, K>) {
        let j = watch.actuator;
        let kind = self.fit(j, &self.sums[j]);
        // told again only for another kind, or a value or factor that moved by more than
        // the actuator's resolution
        let (lo, hi) = self.ranges[j];
        let reach = lo.abs().max(hi.abs());
        let res = self.config.resolution[j];
        let same = match (kind, watch.kind) {
            (Kind::Dead, Kind::Dead) => true,
            (Kind::Dead, Kind::Stuck(v)) | (Kind::Stuck(v), Kind::Dead) => v.abs() <= res,
            (Kind::Stuck(a), Kind::Stuck(b)) => (a - b).abs() <= res,
            (Kind::Weak(a), Kind::Weak(b)) => (a - b).abs() * reach <= res,
            _ => false,
        };
        if same {
            return;
        }
        let d = Detection {
            actuator: j,
            kind,
            statistic: self.last.best,
            since: 0,
            refined: true,
        };
        self.conclude(d, control);
        if self.telling {
            // told over the cycles after: until it is in force the allocator believes the old
            // kind, and the watch goes on taking the actuator's shortfall out of each entry
            // (without an end), as it did before
            self.watch = Some(Watch {
                left: usize::MAX,
                ..*watch
            });
        }
    }

    /// Tells the allocator of detection `d` and reports it, at once, or over the cycles that
    /// follow when the tell moves the actuator's factor (a weak one's, or one told weak
    /// before found dead or stuck): its reweighting is then formed a few columns a cycle, in
    /// place of the test, and `d` told and reported once it is in force, its `since` counting
    /// the wait (docs/maths.md, "Failure detection", *A weak actuator told over cycles*).
    #[inline(always)]
    fn conclude(&mut self, d: Detection<T>, control: &mut VehicleControl<T, K>) {
        let j = d.actuator;
        // a weak kind always (one whose factor is the one told is told at the first step),
        // a dead or stuck one whose factor was told before (`Kind::tell` sets it back to 1)
        let later = match d.kind {
            Kind::Weak(_) => true,
            Kind::Dead | Kind::Stuck(_) => control.factors().get(j).is_some_and(|f| *f != T::one()),
        };
        if later {
            self.stage(d, control);
        } else {
            self.tell(j, d.kind, control);
            self.report(d);
        }
    }

    /// A period without a step of the detection being told (a gap, or the settling after
    /// it): counted in its wait all the same.
    #[cold]
    fn idle(&mut self) {
        if let Some(t) = self.staged.as_mut() {
            t.waited += 1;
        }
    }

    /// Keeps `d` to tell over the cycles that follow ([`Detector::conclude`]).
    #[cold]
    #[inline(never)]
    fn stage(&mut self, d: Detection<T>, control: &mut VehicleControl<T, K>) {
        // (one at a time: the test, which finds the next, does not run while one is told)
        if let Some(t) = self.staged.take() {
            let (j, kind) = (t.detection.actuator, t.detection.kind);
            self.tell(j, kind, control);
            self.report(t.detection);
        }
        self.telling = true;
        self.staged = Some(Telling {
            detection: d,
            waited: 0,
            reweighting: None,
        });
    }

    /// One cycle's step of the detection told over cycles ([`Detector::conclude`]): its
    /// reweighting begun, or stepped on ([`COLUMNS`] more columns of its updates, or its
    /// weights), or, once nothing is left, put in force with the rest of the kind, the
    /// detection reported.
    #[inline(never)]
    fn step(&mut self, control: &mut VehicleControl<T, K>) {
        let read = self.told == Some(control.told());
        let Some(t) = self.staged.as_mut() else {
            self.telling = false;
            return;
        };
        t.waited += 1;
        let (j, kind) = (t.detection.actuator, t.detection.kind);
        match t.reweighting.as_mut() {
            None => {
                t.reweighting = control.reweighting(j, kind.factor());
                if t.reweighting.is_some() {
                    return;
                }
                // nothing to reweight (the factor was told meanwhile): told at once
                kind.tell(j, control);
            }
            Some(r) => {
                if !control.advance(r, COLUMNS) {
                    return;
                }
                kind.tell_reweighted(j, control, r);
            }
        }
        let mut d = t.detection;
        d.since += t.waited;
        self.staged = None;
        self.telling = false;
        if d.refined {
            // the watch kept over a refinement's tell ends with it
            self.watch = None;
        }
        self.told_now(j, read, control);
        self.report(d);
    }

    /// Tells the allocator what actuator `j` is now believed to be, forgetting what it was
    /// told before: held at 0 or at a value, or its column scaled.
    #[inline(always)]
    fn tell(&mut self, j: usize, kind: Kind<T>, control: &mut VehicleControl<T, K>) {
        let read = self.told == Some(control.told());
        kind.tell(j, control);
        self.told_now(j, read, control);
    }

    /// What the detector keeps of a tell of actuator `j`: found failed, and the holds as the
    /// allocator now has them (`read`: they were read since the last tell before it).
    #[inline(always)]
    fn told_now(&mut self, j: usize, read: bool, control: &VehicleControl<T, K>) {
        self.failed[j] = true;
        // the holds read still stand but for this one (unless told since they were read)
        if read {
            self.stuck[j] = control.held(j);
            self.told = Some(control.told());
        }
    }

    /// The entry that leaves the older window when the next is kept, taken off its sum
    /// (none while the windows fill), when the two windows fill the ring: before the next
    /// entry's residual is written in its slot, since that is then the one that leaves.
    /// Otherwise [`Detector::push`] takes it off, in its pass over the sums.
    fn leave(&mut self) {
        let wn = self.config.window;
        // (with a slot between them, `push` takes it off in its own pass instead)
        if self.len >= 2 * wn && 2 * wn == CAPACITY {
            let i = (self.head + CAPACITY - 2 * wn) % CAPACITY;
            self.windows.older -= &self.ring[i].w;
        }
    }

    /// Keeps the entry written in the slot at `head`, and moves the windows' sums on with it:
    /// the entry that passes from the recent window to the older one moves between their
    /// sums, and the one that leaves the older window is taken off (by [`Detector::leave`]
    /// already when its slot is this one).
    fn push(&mut self) {
        let wn = self.config.window;
        let s = &mut self.windows;
        let w = &self.ring[self.head].w;
        // one pass over the axes: the recent sum less the entry that moves on to the older
        // window, plus the new one, and the older sum less the entry that leaves it (unless
        // `leave` took it off, its slot being this one), plus the one that moves on (each in
        // that order), and the block's sum
        if self.len >= 2 * wn && 2 * wn < CAPACITY {
            let moved = &self.ring[(self.head + CAPACITY - wn) % CAPACITY].w;
            let leaving = &self.ring[(self.head + CAPACITY - 2 * wn) % CAPACITY].w;
            for i in 0..K {
                s.recent[i] = (s.recent[i] - moved[i]) + w[i];
                s.older[i] = (s.older[i] - leaving[i]) + moved[i];
                s.block[i] += w[i];
            }
        } else if self.len >= wn {
            let moved = &self.ring[(self.head + CAPACITY - wn) % CAPACITY].w;
            for i in 0..K {
                s.recent[i] = (s.recent[i] - moved[i]) + w[i];
                s.older[i] += moved[i];
                s.block[i] += w[i];
            }
        } else {
            for i in 0..K {
                s.recent[i] += w[i];
                s.block[i] += w[i];
            }
        }
        s.filled += 1;
        if s.filled == wn {
            // afresh: the recent window is this block, the older one the block before
            s.recent = s.block;
            s.older = s.before;
            s.before = s.block;
            s.block = SVector::zeros();
            s.filled = 0;
        }
        self.head = (self.head + 1) % CAPACITY;
        self.len = (self.len + 1).min(CAPACITY);
        if self.pending {
            self.job.shift += 1;
        }
    }

    /// The test on full windows: learn the spread while calibrating or nominal; otherwise
    /// isolate, and prepare the leading actuator's change point; once it has led the tests of
    /// `confirm − 1` entries, arm its naming in the next entry (with `confirm` 1, name it
    /// now).
    fn test(&mut self, control: &mut VehicleControl<T, K>) {
        let wn = self.config.window;
        self.last.testing = false;
        if self.len < 2 * wn {
            return;
        }
        if self.warmed < self.config.warmup {
            self.warmed += 1;
            return;
        }
        // the change of the windows' means, turned into body axes
        let n = self.window_n;
        let d = body_blocks(
            &self.rotation,
            &((self.windows.recent - self.windows.older) / n),
        );
        if self.learned < self.calibration_n {
            self.learned += T::one();
            self.variance += (d.component_mul(&d) - self.variance) / self.learned;
            // the first whitening, one step in each of the calibration's last entries, from
            // the spread learned by then (the calibration lasts at least two windows, and
            // [`Detector::check`] holds it longer than the steps)
            if self.learned + self.whitening.steps > self.calibration_n {
                self.renew();
            }
            return;
        }
        // a calibration shorter than the steps completes the first whitening here
        while !self.whitening.ready {
            self.renew();
        }
        let inverse = self.whitening.inverse;
        let z = d.component_mul(&inverse);
        let total = d.dot(&z);
        let (best, second) = self.bank(&z);
        self.last = Statistic {
            actuator: best.0,
            best: best.1,
            second,
            total,
            testing: true,
        };
        if best.1 <= self.config.threshold {
            self.variance += (d.component_mul(&d) - self.variance) * self.config.memory;
            self.alarmed = false;
            self.streak = (0, 0);
            // the whitening is renewed in nominal entries, as the spread is learned, but not
            // while an actuator is watched (the entries that carry the watch)
            if self.watch.is_none() {
                self.renew();
            }
            return;
        }
        if !self.alarmed {
            self.alarmed = true;
            self.alarms = self.alarms.saturating_add(1);
        }
        let gate = self.config.isolation + self.config.relative * total;
        if total - best.1 >= gate || best.1 - second < self.config.margin {
            // a change no single actuator explains (not a failure), or one that two explain
            // about as well (not yet isolated)
            self.streak = (0, 0);
            return;
        }
        self.streak = if self.streak.1 > 0 && self.streak.0 == best.0 {
            (best.0, self.streak.1 + 1)
        } else {
            (best.0, 1)
        };
        let confirm = self.config.confirm;
        if self.streak.1 == 1 {
            self.prepare(best.0);
        } else {
            self.project();
        }
        if confirm == 1 {
            // named in the cycle of its one test
            self.streak = (0, 0);
            self.alarmed = false;
            self.found(best.0, best.1, self.windows.older / n, control);
        } else if self.streak.1 + 1 == confirm {
            // named in the next entry, without a test
            self.streak = (0, 0);
            self.alarmed = false;
            self.armed = Some((best.0, best.1));
        }
    }

    /// The change point of actuator `j`, which leads the tests from this entry on, prepared
    /// ahead (docs/maths.md, "Failure detection", paragraph "The kind, prepared ahead"): its
    /// weights in world axes at this attitude (its column is turned there later,
    /// [`Detector::turn`]), and the entries of the window its
    /// naming would read (the naming comes `confirm − 1` entries after this one) to project
    /// over the tests before the naming's entry (which projects its own).
    fn prepare(&mut self, j: usize) {
        let w = &self.whitening;
        let weights = self.columns[j].component_mul(&w.inverse) / w.norms[j];
        // the column is turned into world axes at this attitude later ([`Detector::turn`])
        self.along[0] = rotate_blocks(&self.rotation, &weights);
        let c = self.config.confirm;
        self.prep = Prep {
            weights,
            next: (self.head + CAPACITY - 1 - (self.config.window - c)) % CAPACITY,
            // the tests before the naming's entry (which projects its own)
            cycles: c.saturating_sub(2).max(1),
            rotation: self.rotation,
            turned: false,
            actuator: j,
        };
    }

    /// The prepared actuator's column turned into world axes at the attitude of its first
    /// lead (`along[1]`), once.
    fn turn(&mut self) {
        if !self.prep.turned {
            self.prep.turned = true;
            self.along[1] = rotate_blocks(&self.prep.rotation, &self.columns[self.prep.actuator]);
        }
    }

    /// Projects this cycle's share of the entries kept since the prepared actuator's last
    /// projection ([`Detector::prepare`]): all of them in the naming's cycle.
    fn project(&mut self) {
        self.turn();
        let p = &mut self.prep;
        let left = (self.head + CAPACITY - p.next) % CAPACITY;
        let now = left.div_ceil(p.cycles.max(1));
        p.cycles = p.cycles.saturating_sub(1);
        for _ in 0..now {
            self.proj[p.next] = self.along[0].dot(&self.ring[p.next].w);
            p.next = (p.next + 1) % CAPACITY;
        }
    }

    /// One step of renewing the whitening the test uses (docs/maths.md, "Failure detection",
    /// paragraph "The whitening, renewed a step at a time"): the first takes the learned spread, floored, as the next `s⁻²`; each of
    /// the next forms one actuator's `|b̃_j|²` with it; after the last the pair is taken in
    /// whole, so the test always whitens the change and the columns by the same spread.
    fn renew(&mut self) {
        let w = &mut self.whitening;
        if w.step == 0 {
            w.next = self
                .variance
                .zip_map(&self.floor2, |v, f| T::one() / if v > f { v } else { f });
        } else {
            let j = w.step - 1;
            w.norms_next[j] = self.squares[j].dot(&w.next);
        }
        w.step += 1;
        if w.step > self.formed {
            w.inverse = w.next;
            w.norms = w.norms_next;
            w.step = 0;
            w.ready = true;
        }
    }

    /// Actuator `j` named with statistic `t`, and the older window's mean `older`: in the
    /// same cycle the change point over the window, the kind fitted, and the allocator told
    /// and the detection reported, so that the allocation reconfigures at once, or, where the
    /// tell reweights the allocator, both over the cycles after ([`Detector::conclude`]); the
    /// shortfalls are taken out of the window over the next cycles ([`Detector::take`]),
    /// after that. A watch still running is cut short, its kind fitted again in a cycle
    /// after; the named actuator is watched from the next entry on
    /// (docs/maths.md, "Failure detection", paragraph "The kind").
    fn found(&mut self, j: usize, t: T, older: SVector<T, K>, control: &mut VehicleControl<T, K>) {
        if self.watch.is_some() {
            self.ending = self.watch.take();
        }
        // the entries the change point reads not projected yet (the naming's own, or the
        // whole window when the confirmation is shorter than three entries)
        self.turn();
        while self.prep.next != self.head {
            let at = self.prep.next;
            self.proj[at] = self.along[0].dot(&self.ring[at].w);
            self.prep.next = (at + 1) % CAPACITY;
        }
        debug_assert!(
            (0..self.config.window).all(|i| {
                let at = (self.head + CAPACITY - 1 - i) % CAPACITY;
                self.proj[at] == self.along[0].dot(&self.ring[at].w)
            }),
            "the window's entries are projected on the named actuator's weights"
        );
        // a new failure of this actuator: what it showed before is another story
        let (span, sums) = self.change(j, self.along[0].dot(&older));
        self.sums[j] = sums;
        let kind = self.fit(j, &sums);
        self.watch = Some(Watch {
            actuator: j,
            left: self.config.window,
            baseline: older,
            weights: self.prep.weights,
            kind,
        });
        let d = Detection {
            actuator: j,
            kind,
            statistic: t,
            since: span * self.config.decimation + self.periods,
            refined: false,
        };
        self.conclude(d, control);
        self.job = Pending {
            span,
            ..Pending::zero()
        };
        self.pending = true;
    }

    /// The bank of hypotheses (docs/maths.md, "Failure detection"): for each actuator `j`,
    /// `T_j = (b_jᵀ z)² / (b_j ∘ b_j)ᵀ s⁻²` with `z = d ⊘ s²` the change in body axes over its
    /// spread squared, which is `(b̃_jᵀ d̃)² / |b̃_j|²` of the whitened column and change;
    /// the best `(j, T_j)` and the runner-up's `T`.
    fn bank(&self, z: &SVector<T, K>) -> ((usize, T), T) {
        let (mut best, mut second) = ((0, T::zero()), T::zero());
        for j in 0..self.formed {
            let nb = self.whitening.norms[j];
            if nb > T::zero() {
                let dot = self.columns[j].dot(z);
                let t = dot * dot / nb;
                if t > best.1 {
                    second = best.1;
                    best = (j, t);
                } else if t > second {
                    second = t;
                }
            }
        }
        (best, second)
    }

    /// The named actuator `j`'s change point over the window
    /// (docs/maths.md, "Failure detection", paragraph "The kind"): the thrust short of what
    /// was believed in each entry, newest first, along its whitened column (`gᵀw − base`,
    /// from the projections prepared ahead), kept in `shorts`; the start whose mean shift
    /// is most significant, as the number of entries from the newest; and the sums of the
    /// actual thrust over the change (the believed thrust plus the shortfall), newest first,
    /// summed over the change alone once its start is known.
    fn change(&mut self, j: usize, base: T) -> (usize, Sums<T>) {
        let (mut sum, mut n, mut score, mut span) = (T::zero(), T::zero(), T::zero(), 1);
        for i in 0..self.config.window {
            let at = (self.head + CAPACITY - 1 - i) % CAPACITY;
            let short = self.proj[at] - base;
            self.shorts[i] = short;
            sum += short;
            n += T::one();
            let t = sum * sum / n;
            if t > score || i == 0 {
                score = t;
                span = i + 1;
            }
        }
        // the sums over the change alone, newest first: the same operations in the same
        // order as a running sum over the whole window, stopped at its start
        let mut sums = Sums::zero();
        for i in 0..span {
            let e = &self.ring[(self.head + CAPACITY - 1 - i) % CAPACITY];
            sums.add(e.u[j], e.p[j] + self.shorts[i]);
        }
        (span, sums)
    }

    /// Up to `chunk` more of the named actuator's shortfalls over the `p.span` entries of its
    /// change (as the change point measured them), each taken out of its entry's residual
    /// and of the sums of the window and the block it is in (they are explained now).
    fn take(&mut self, chunk: usize) {
        let (wn, filled) = (self.config.window, self.windows.filled);
        let p = &mut self.job;
        let column = self.along[1];
        // the shortfalls taken out of the recent window, the older one, the block being
        // summed and the one before it
        let (mut recent, mut older, mut block, mut before) =
            (T::zero(), T::zero(), T::zero(), T::zero());
        let end = (p.done + chunk).min(p.span);
        // (an entry older than the ring, after a long wait behind a weak actuator's tell, is
        // gone from both windows: nothing to take out)
        for i in p.done..end.min(CAPACITY.saturating_sub(p.shift)) {
            let age = i + p.shift;
            let e = &mut self.ring[(self.head + CAPACITY - 1 - age) % CAPACITY];
            let short = self.shorts[i];
            for (w, c) in e.w.iter_mut().zip(column.iter()) {
                *w -= *c * short;
            }
            if age < wn {
                recent += short;
            } else if age < 2 * wn {
                older += short;
            }
            if age < filled {
                block += short;
            } else if age < filled + wn {
                before += short;
            }
        }
        p.done = end;
        let w = &mut self.windows;
        w.recent -= column * recent;
        w.older -= column * older;
        w.block -= column * block;
        w.before -= column * before;
    }

    /// The least penalised kind for the sums of actuator `j` (BIC: `n ln(RSS/n) + p ln n`,
    /// the RSS floored at the actuator's resolution): dead (`y = 0`), stuck (`y = v`, `v` the
    /// mean within the bounds) or weak (`y = k u`, `k` in (0, 1) by least squares, and only
    /// when its BIC is lower than the others' by 6, strong evidence). The BICs are compared
    /// without a logarithm (docs/maths.md, "Failure detection", paragraph "The kind"): a model
    /// with a parameter beats dead when its floored RSS is below dead's times `n^(−1/n)`, and
    /// weak beats the best by 6 when its RSS is below the best's times `e^(−6/n)`.
    fn fit(&self, j: usize, sums: &Sums<T>) -> Kind<T> {
        choose(
            sums,
            self.ranges[j],
            self.config.resolution[j],
            &self.penalties,
        )
    }
}

/// [`Detector::fit`] for an actuator of bounds `(lo, hi)` and resolution `res`.
fn choose<T: Real>(
    sums: &Sums<T>,
    (lo, hi): (T, T),
    res: T,
    table: &[(T, T); PENALTIES],
) -> Kind<T> {
    let n = sums.n;
    let floor = n * res * res;
    let two: T = eqtrack_controller::real(2.0);
    // (comparisons rather than `max` and `min`: the same values, a NaN among them taken as
    // the bound, but for the sign of a zero that ties a bound, in a few instructions where a
    // microcontroller's `maxnum` takes about twenty)
    let q = |rss: T| if rss > T::zero() { rss } else { T::zero() } + floor;
    let (penalty, strong) = penalties(sums.count, table);
    // dead's floored RSS, as a model with a parameter would need it to tie
    let mut best = (Kind::Dead, q(sums.yy) * penalty);
    let v = sums.y / n;
    let v = if v > lo { v } else { lo };
    let v = if v < hi { v } else { hi };
    let stuck = q(sums.yy - two * v * sums.y + n * v * v);
    if stuck < best.1 {
        best = (Kind::Stuck(v), stuck);
    }
    if sums.uu > T::zero() {
        let k = sums.uy / sums.uu;
        if k > T::zero() && k < T::one() {
            // a weak actuator only on strong evidence: while its command has not moved,
            // weak and stuck fit alike, and stuck is reported
            let weak = q(sums.yy - two * k * sums.uy + k * k * sums.uu);
            if weak < best.1 * strong {
                best = (Kind::Weak(k), weak);
            }
        }
    }
    best.0
}

/// The BIC's factors for `n` entries, `n^(−1/n)` and `e^(−6/n)` ([`Detector::fit`]): from
/// `table` (formed by [`penalty_table`]) up to its length, computed beyond it.
fn penalties<T: Real>(n: usize, table: &[(T, T); PENALTIES]) -> (T, T) {
    match table.get(n) {
        Some(p) => *p,
        None => penalty(n),
    }
}

/// Entries the BIC's factors are tabled for: a change and a watch are a window each at most.
const PENALTIES: usize = CAPACITY + 1;

/// `n^(−1/n)` and `e^(−6/n)` ([`Detector::fit`]; 1 and 0 for no entry).
fn penalty<T: Real>(n: usize) -> (T, T) {
    if n == 0 {
        return (T::one(), T::zero());
    }
    let x: T = eqtrack_controller::real(n as f64);
    let six: T = eqtrack_controller::real(6.0);
    ((-x.ln() / x).exp(), (-six / x).exp())
}

/// The BIC's factors for 0 to `PENALTIES − 1` entries.
fn penalty_table<T: Real>() -> [(T, T); PENALTIES] {
    core::array::from_fn(penalty)
}

/// The momentum the body's gyroscopic term turns, `μ` plus the wheels' `h_w = Σ J_s (gᵀω + Ω) g`
/// on the torque rows: with wheels `J ω̇ = (J ω + h_w) × ω − Σ g u + τ` (docs/maths.md,
/// "Reaction wheels"). `μ` itself without wheels.
fn with_wheels<T: Real, const K: usize>(
    mu: SVector<T, K>,
    v: &SVector<T, K>,
    speeds: &[T],
    control: &VehicleControl<T, K>,
) -> SVector<T, K> {
    let mut carried = mu;
    if !speeds.is_empty() {
        let omega = nalgebra::Vector3::new(v[0], v[1], v[2]);
        let h = control.wheels().momentum(&omega, speeds);
        for i in 0..K.min(3) {
            carried[i] += h[i];
        }
    }
    carried
}

/// `blockdiag(Rᵀ, Rᵀ) w`: a world-axes wrench in body axes (the inverse of
/// [`rotate_blocks`]).
fn body_blocks<T: Real, const K: usize>(r: &Matrix3<T>, w: &SVector<T, K>) -> SVector<T, K> {
    let mut out = *w;
    for b in 0..K / 3 {
        let v = r.tr_mul(&w.fixed_rows::<3>(3 * b));
        out.fixed_rows_mut::<3>(3 * b).copy_from(&v);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_chacha::rand_core::{Rng, SeedableRng};

    /// The BICs themselves, with their logarithms (`n ln(RSS'/RSS'_dead) + p ln n`, the
    /// margins of the two comparisons beside the kind): the fit as it was written first.
    fn by_logarithms(sums: &Sums<f64>, (lo, hi): (f64, f64), res: f64) -> (Kind<f64>, f64) {
        let n = sums.n;
        let floor = n * res * res;
        let q = |rss: f64| rss.max(0.0) + floor;
        let dead = q(sums.yy);
        let score = |rss: f64| n * (q(rss) / dead).ln() + n.ln();
        let mut best = (Kind::Dead, 0.0);
        let v = (sums.y / n).clamp(lo, hi);
        let b = score(sums.yy - 2.0 * v * sums.y + n * v * v);
        let mut margin = b.abs();
        if b < best.1 {
            best = (Kind::Stuck(v), b);
        }
        if sums.uu > 0.0 {
            let k = sums.uy / sums.uu;
            if k > 0.0 && k < 1.0 {
                let b = score(sums.yy - 2.0 * k * sums.uy + k * k * sums.uu);
                margin = margin.min((b - (best.1 - 6.0)).abs());
                if b < best.1 - 6.0 {
                    best = (Kind::Weak(k), b);
                }
            }
        }
        (best.0, margin)
    }

    /// The fit without logarithms chooses the kind the BICs choose, wherever no comparison
    /// is within 1e-9 of a tie: over seeded sums of dead, stuck and weak actuators, noisy or
    /// not, commanded still or moving, from one entry to beyond the table.
    #[test]
    fn the_fit_without_logarithms_chooses_as_the_bics_do() {
        let table = penalty_table::<f64>();
        let mut rng = ChaCha8Rng::seed_from_u64(0x0b1c);
        let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let (mut compared, mut kinds) = (0, [0; 3]);
        for case in 0..20_000 {
            let count = 1 + (unit() * 80.0) as usize;
            let (lo, hi) = (-40.0, 40.0);
            let res = 0.2 * unit();
            let model = case % 3;
            let (value, factor) = (-40.0 + 80.0 * unit(), unit());
            let (still, noise) = (unit() < 0.3, 5.0 * unit() * unit());
            let mut sums = Sums::zero();
            let u0 = -40.0 + 80.0 * unit();
            for _ in 0..count {
                let u = if still { u0 } else { -40.0 + 80.0 * unit() };
                let y = match model {
                    0 => 0.0,
                    1 => value,
                    _ => factor * u,
                } + noise * (unit() - 0.5);
                sums.add(u, y);
            }
            let (want, margin) = by_logarithms(&sums, (lo, hi), res);
            let got = choose(&sums, (lo, hi), res, &table);
            if margin > 1e-9 {
                compared += 1;
                assert_eq!(got, want, "case {case}: {count} entries, margin {margin}");
            }
            kinds[got.code() as usize % 3] += 1;
        }
        assert!(compared > 19_000, "only {compared} cases away from a tie");
        assert!(kinds.iter().all(|k| *k > 1_000), "kinds chosen {kinds:?}");
    }

    /// The table holds the factors themselves: `n^(−1/n)` and `e^(−6/n)`.
    #[test]
    fn the_tabled_factors_are_the_bics() {
        let table = penalty_table::<f64>();
        for n in 1..PENALTIES + 10 {
            let (a, s) = penalties(n, &table);
            let x = n as f64;
            assert!((a.ln() * x + x.ln()).abs() < 1e-12, "n^(-1/n) at {n}");
            assert!((s.ln() * x + 6.0).abs() < 1e-12, "e^(-6/n) at {n}");
        }
    }
}
