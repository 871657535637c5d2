//! The `error_frame` Monte Carlo on SE(3): EqT with its error formed at the reference
//! (`reference`), in the world frame (`world`, the papers' law) and in a world frame
//! re-centred at the reference (`recentred`), flown from the same random starts in a world
//! moved far away. The results:
//! docs/simulations.md, "Where the world frame is: the error_frame Monte Carlo".
//!
//! Run `i` draws, from one ChaCha8 stream seeded with `--seed`, in run order (so the numbers
//! do not depend on the thread count): the attitude offset `Rz(a)Ry(b)Rx(c)` with `a, b, c`
//! uniform on [−π, π]; a position offset uniform in a ball of [`POSITION_BALL`] m; a twist
//! offset `N(0, 1)` per axis; and a world motion `T = (Rz(ψ), t)`, `t` uniform in a ball of
//! [`WorldMotion::radius`] and `ψ` uniform on `[−turn, turn]`. The body starts at
//! `Q(0) = T·(R_d(0)·Rz(a)Ry(b)Rx(c), x_d(0) + offset)`, `V(0) = V_d(0) + twist`, and the
//! reference flown is the scenario's, every pose left-multiplied by `T` (the reference
//! integrated from `T·Q_d(0)`: its body velocities and feedforward do not depend on where the
//! world is). Every frame flies the same draw.

use crate::montecarlo::{euler_zyx, in_pool};
use crate::rejection::angle;
use eqtrack_controller::closed_loop::{ClosedLoop, Sample};
use eqtrack_controller::group::se3::{from_parts, rotation, translation};
use eqtrack_controller::group::{GroupKind, Se3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::Desired;
use eqtrack_controller::reference::{Tabulated, Trajectory};
use eqtrack_controller::tracking::lyapunov;
use eqtrack_controller::{ControllerConfig, ErrorFrame, Law};
use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3};
use plant::SimError;
use plant::output::num;
use plant::plot::{Line, Panel, law_color, render};
use plant::trajectory::input;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal, Uniform};
use rayon::prelude::*;
use scenario::Scenario;
use std::f64::consts::PI;
use std::path::Path;

/// The radius (m) of the ball the initial position offset is drawn from.
pub const POSITION_BALL: f64 = 5.0;
/// The time (s) at the end of a run over which a converged run stays within [`CONVERGED`].
pub const WINDOW: f64 = 5.0;
/// A converged run's bound on the attitude error (rad) and on the position error (m).
pub const CONVERGED: f64 = 1e-3;
/// A settled run's bound on the attitude error (rad) and on the position error (m).
pub const SETTLED: f64 = 0.1;
/// The most points per run kept for the figure's means.
const FIGURE_POINTS: u64 = 1000;

/// The world motions drawn: a translation uniform in a ball of `radius` m and a turn about
/// z uniform on `[−turn, turn]` rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldMotion {
    /// The radius (m) of the translation's ball.
    pub radius: f64,
    /// The largest turn about z (rad).
    pub turn: f64,
}

impl Default for WorldMotion {
    /// 10 km and π.
    fn default() -> Self {
        WorldMotion {
            radius: 1e4,
            turn: PI,
        }
    }
}

impl WorldMotion {
    /// Refuses a negative or non-finite radius or turn, naming the flag.
    pub fn check(&self) -> Result<(), SimError> {
        for (flag, x) in [("--world-radius", self.radius), ("--world-turn", self.turn)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(SimError::Input(format!(
                    "{flag}: must be a finite number >= 0, got {x}"
                )));
            }
        }
        Ok(())
    }
}

/// One run's draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draw {
    /// `(a, b, c)` (rad): `R(0) = R_d(0)·Rz(a)Ry(b)Rx(c)` before the world motion.
    pub euler: [f64; 3],
    /// `x(0) = x_d(0) + offset` (m) before the world motion.
    pub offset: [f64; 3],
    /// `V(0) = V_d(0) + twist`, body frame, `(ω, v)`.
    pub twist: [f64; 6],
    /// The world motion's translation `t` (m).
    pub shift: [f64; 3],
    /// The world motion's turn `ψ` about z (rad).
    pub turn: f64,
}

impl Draw {
    /// The world motion `T = (Rz(ψ), t)`.
    pub fn world(&self) -> Matrix4<f64> {
        let (s, c) = self.turn.sin_cos();
        let rz = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        from_parts(&rz, &Vector3::from(self.shift))
    }

    /// The initial pose and twist for a reference starting at `desired`, world motion
    /// included.
    pub fn initial(&self, desired: &Desired<f64, 4, 6>) -> (Matrix4<f64>, SVector<f64, 6>) {
        let [a, b, c] = self.euler;
        let r = rotation(&desired.q) * euler_zyx(a, b, c);
        let x = translation(&desired.q) + Vector3::from(self.offset);
        (
            self.world() * from_parts(&r, &x),
            desired.v + SVector::<f64, 6>::from(self.twist),
        )
    }
}

/// A point uniform in the ball of `radius` about the origin: a direction from three
/// normal draws, then the radius from one uniform draw (`radius·u^(1/3)`).
fn in_ball(rng: &mut ChaCha8Rng, unit: &Uniform<f64>, radius: f64) -> [f64; 3] {
    let dir: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(rng));
    let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    let scale = radius * unit.sample(rng).cbrt() / norm.max(f64::MIN_POSITIVE);
    // + 0.0: a zero radius gives +0, not −0
    dir.map(|x| x * scale + 0.0)
}

/// Draws `runs` draws from the stream seeded with `seed`. The stream is the same whatever
/// the world motion's size: `world` only scales its draws (zero: no motion, the same starts).
pub fn draw(runs: usize, seed: u64, world: WorldMotion) -> Vec<Draw> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // non-empty ranges: `new` cannot fail here
    let angle = Uniform::new(-PI, PI).expect("valid range");
    let unit = Uniform::new(0.0, 1.0).expect("valid range");
    let sym = Uniform::new(-1.0, 1.0).expect("valid range");
    (0..runs)
        .map(|_| {
            let a = angle.sample(&mut rng);
            let b = angle.sample(&mut rng);
            let c = angle.sample(&mut rng);
            let offset = in_ball(&mut rng, &unit, POSITION_BALL);
            let twist: [f64; 6] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            let shift = in_ball(&mut rng, &unit, world.radius);
            let turn = world.turn * sym.sample(&mut rng) + 0.0;
            Draw {
                euler: [a, b, c],
                offset,
                twist,
                shift,
                turn,
            }
        })
        .collect()
}

/// What one run of one frame produced.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRun {
    /// The run index.
    pub run: usize,
    /// The error frame flown.
    pub frame: ErrorFrame,
    /// The draw.
    pub draw: Draw,
    /// Flew to the end and stayed within [`CONVERGED`] (attitude and position) over the last
    /// [`WINDOW`] s.
    pub converged: bool,
    /// The first time after which the attitude error stays below [`SETTLED`] rad and the
    /// position error below [`SETTLED`] m to the end (`None`: not by the end, or the run
    /// stopped).
    pub settling_time: Option<f64>,
    /// `Σ ‖τ_k‖·h` over the torques held (`t_k < T`, or up to a stop).
    pub effort: f64,
    /// Flew the whole duration (did not stop).
    pub finished: bool,
    /// T, or the time at which the run stopped (the loop refused to step).
    pub t_end: f64,
    /// L at the last step flown (see [`metrics`]).
    pub final_lyapunov: f64,
    /// The attitude error (rad) at the last step flown.
    pub final_attitude_error: f64,
    /// `|x − x_d|` (m) at the last step flown.
    pub final_position_error: f64,
    /// Why the run did not converge (`None` when it did): the loop's error when it stopped,
    /// else the largest errors over the last [`WINDOW`] s.
    pub reason: Option<String>,
    /// Every few steps (see [`series_stride`]): attitude error, position error, `‖τ‖`, L.
    pub series: Vec<[f64; 4]>,
}

/// The step between two kept points of a run's series (at most about 1000 points).
pub fn series_stride(steps: u64) -> u64 {
    steps.div_ceil(FIGURE_POINTS).max(1)
}

/// What a step of the study records, world-independent (the same for any world motion):
/// the attitude error as the geodesic angle of `R_dᵀR` (rad, from `‖I − R_dᵀR‖_F` by
/// [`angle`]), the position error `|x − x_d|` (m), `‖τ‖`, and the transported-error Lyapunov
/// function `L = ½eᵀIe + Υ(Q_L)`, `Q_L = Q_d⁻¹Q`, `e = V − Ad_{Q_L⁻¹}V_d` (the errors
/// `ControllerConfig::errors` forms at the reference, with the model inertia `I` and the
/// potential weight `K` of `config`): the same L for every frame, the one the `reference` law
/// decreases.
pub fn metrics(sample: &Sample<f64, 4, 6>, config: &ControllerConfig<f64, 4, 6>) -> [f64; 4] {
    let d = &sample.desired;
    let r_err = rotation(&d.q).tr_mul(&rotation(&sample.q));
    let position = (translation(&sample.q) - translation(&d.q)).norm();
    let at_reference = ControllerConfig {
        law: Law::Eqt,
        error_frame: ErrorFrame::Reference,
        ..*config
    };
    let (error, e) = at_reference.errors::<Se3>(&sample.q, &sample.v, d);
    [
        angle((Matrix3::identity() - r_err).norm()),
        position,
        sample.output.torque.norm(),
        lyapunov(&error.q, &e, &config.inertia, &config.k).total,
    ]
}

/// The scenario's reference, every pose left-multiplied by the world motion.
struct Moved<'a> {
    inner: Tabulated<'a, f64, 4, 6>,
    world: Matrix4<f64>,
}

impl Trajectory<f64, 4, 6> for Moved<'_> {
    fn time(&self) -> f64 {
        self.inner.time()
    }
    fn period(&self) -> f64 {
        self.inner.period()
    }
    fn step_index(&self) -> u64 {
        self.inner.step_index()
    }
    fn desired(&self) -> Desired<f64, 4, 6> {
        let d = self.inner.desired();
        Desired {
            q: self.world * d.q,
            ..d
        }
    }
    fn advance(&mut self) {
        self.inner.advance();
    }
}

/// Refuses a base scenario the study does not fly: another group, sensors, a vehicle, a
/// world-frame disturbance or disturbance-rejection terms (the study compares the bare laws
/// on the exact state of a bare body).
pub fn check_base(s: &Scenario) -> Result<(), SimError> {
    let refuse = |what: &str| {
        Err(SimError::Input(format!(
            "scenario `{}`: the error_frame study flies the bare law on a bare body, without {what}",
            s.name
        )))
    };
    if s.group != GroupKind::Se3 {
        return Err(SimError::Input(format!(
            "scenario `{}`: the error_frame study is defined on se3, not {}",
            s.name,
            s.group.name()
        )));
    }
    if s.sensors.is_some() {
        return refuse("[sensors]");
    }
    if s.vehicle.is_some() {
        return refuse("[vehicle]");
    }
    if s.disturbance_world.is_some() {
        return refuse("disturbance_world");
    }
    if s.rejection.observer.is_some() || s.rejection.integral.is_some() {
        return refuse("disturbance-rejection terms");
    }
    Ok(())
}

/// Flies every (draw, frame) pair of the study on `base` (see the module's documentation);
/// results ordered by run, then by the order of `frames`. A run that stops (the law refuses
/// a state, say) is a result, with its reason. Once `stop` is set, runs not yet started are
/// skipped: the result holds the runs that finished (check the flag afterwards).
pub fn run_study(
    base: &Scenario,
    draws: &[Draw],
    frames: &[ErrorFrame],
    threads: Option<usize>,
    on_done: &(dyn Fn() + Sync),
    stop: &link::StopFlag,
) -> Result<Vec<FrameRun>, SimError> {
    check_base(base)?;
    let mut scenarios = Vec::with_capacity(frames.len());
    for frame in frames {
        let mut s = base.clone();
        s.law = Law::Eqt;
        s.error_frame = *frame;
        s.controller::<Se3, 4, 6>().map_err(input(&s))?;
        scenarios.push(s);
    }
    // The reference is the same for every run and frame: integrated once, moved by each run.
    let mut source = base.reference_source::<Se3, 4, 6>().map_err(input(base))?;
    let mut table = Vec::with_capacity(base.steps() as usize + 1);
    Tabulated::record(&mut source, base.steps() as usize, &mut table);
    Tabulated::new(&table, base.control_period).map_err(input(base))?;
    let jobs: Vec<(usize, &Scenario)> = (0..draws.len())
        .flat_map(|i| scenarios.iter().map(move |s| (i, s)))
        .collect();
    let work = || {
        jobs.par_iter()
            .map(|(i, s)| {
                if stop.requested().is_some() {
                    return Ok(None);
                }
                let r = fly(s, &table, *i, draws[*i]);
                on_done();
                r.map(Some)
            })
            .collect::<Result<Vec<_>, _>>()
            .map(|runs| runs.into_iter().flatten().collect())
    };
    in_pool(threads, work)
}

/// What a run accumulates step by step.
struct Tally {
    steps: u64,
    h: f64,
    window_start: u64,
    stride: u64,
    effort: f64,
    last_unsettled: Option<u64>,
    worst: [f64; 2],
    last: [f64; 4],
    t_end: f64,
    flown: u64,
    series: Vec<[f64; 4]>,
}

impl Tally {
    fn new(s: &Scenario) -> Tally {
        let steps = s.steps();
        let window = (WINDOW / s.control_period).round() as u64;
        Tally {
            steps,
            h: s.control_period,
            window_start: steps.saturating_sub(window),
            stride: series_stride(steps),
            effort: 0.0,
            last_unsettled: None,
            worst: [0.0; 2],
            last: [f64::NAN; 4],
            t_end: 0.0,
            flown: 0,
            series: Vec::with_capacity((steps / series_stride(steps)) as usize + 1),
        }
    }

    fn record(&mut self, k: u64, t: f64, m: [f64; 4]) {
        // a NaN error counts as the worst
        let within = |x: f64, bound: f64| x < bound;
        if k < self.steps {
            self.effort += m[2] * self.h;
        }
        if !(within(m[0], SETTLED) && within(m[1], SETTLED)) {
            self.last_unsettled = Some(k);
        }
        if k >= self.window_start {
            for (w, x) in self.worst.iter_mut().zip(m) {
                *w = if x.is_nan() { f64::INFINITY } else { w.max(x) };
            }
        }
        if k.is_multiple_of(self.stride) {
            self.series.push(m);
        }
        self.last = m;
        self.t_end = t;
        self.flown = k + 1;
    }

    fn finish(
        self,
        run: usize,
        frame: ErrorFrame,
        draw: Draw,
        stopped: Option<(f64, String)>,
    ) -> FrameRun {
        let whole = stopped.is_none() && self.flown == self.steps + 1;
        let converged = whole && self.worst[0] < CONVERGED && self.worst[1] < CONVERGED;
        let settling_time = match (whole, self.last_unsettled) {
            (false, _) => None,
            (true, None) => Some(0.0),
            (true, Some(k)) if k < self.steps => Some((k + 1) as f64 * self.h),
            (true, Some(_)) => None,
        };
        let t_end = stopped.as_ref().map_or(self.t_end, |(t, _)| *t);
        let reason = match stopped {
            Some((_, r)) => Some(r),
            None if converged => None,
            None => Some(format!(
                "over the last {WINDOW} s: attitude error up to {:.3e} rad, position error up to {:.3e} m (bound {CONVERGED:e})",
                self.worst[0], self.worst[1]
            )),
        };
        FrameRun {
            run,
            frame,
            draw,
            converged,
            settling_time,
            effort: self.effort,
            finished: whole,
            t_end,
            final_lyapunov: self.last[3],
            final_attitude_error: self.last[0],
            final_position_error: self.last[1],
            reason,
            series: self.series,
        }
    }
}

/// One run of one frame (`s` has the frame): the closed loop from the draw's start against
/// the moved reference.
fn fly(
    s: &Scenario,
    table: &[Desired<f64, 4, 6>],
    run: usize,
    draw: Draw,
) -> Result<FrameRun, SimError> {
    let (q0, v0) = draw.initial(&table[0]);
    let plant =
        RigidBody::<f64, Se3, 4, 6>::new(SMatrix::from_row_slice(&crate::study_inertia(s)), q0, v0)
            .map_err(|e| SimError::Input(format!("run {run}: {e}")))?;
    let reference = Moved {
        inner: Tabulated::new(table, s.control_period).map_err(input(s))?,
        world: draw.world(),
    };
    let controller = s.controller::<Se3, 4, 6>().map_err(input(s))?;
    let mut sim = ClosedLoop::new(controller, reference, plant, s.plant_substeps)
        .and_then(|l| l.with_disturbance(s.disturbance_vector()))
        .map_err(input(s))?;
    let config = *sim.controller.config();
    let mut tally = Tally::new(s);
    let mut stopped = None;
    for step in 0..=tally.steps {
        let t = sim.time();
        if !s.disturbance_steps.is_empty() {
            sim.set_disturbance(s.disturbance_at(step))
                .map_err(input(s))?;
        }
        match sim.step() {
            Ok(sample) => tally.record(step, t, metrics(&sample, &config)),
            Err(e) => {
                let last = match tally.flown {
                    0 => String::new(),
                    n => format!(
                        " (‖τ‖ = {:.3e} at t = {} s)",
                        tally.last[2],
                        (n - 1) as f64 * s.control_period
                    ),
                };
                stopped = Some((t, format!("stopped at t = {t} s: {e}{last}")));
                break;
            }
        }
    }
    Ok(tally.finish(run, s.error_frame, draw, stopped))
}

/// The columns of `frames.csv`.
pub const CSV_HEADER: [&str; 26] = [
    "run",
    "frame",
    "euler_z",
    "euler_y",
    "euler_x",
    "dx",
    "dy",
    "dz",
    "dwx",
    "dwy",
    "dwz",
    "dvx",
    "dvy",
    "dvz",
    "world_x",
    "world_y",
    "world_z",
    "world_turn",
    "converged",
    "settling_time",
    "effort",
    "t_end",
    "final_lyapunov",
    "final_attitude_error",
    "final_position_error",
    "reason",
];

/// Writes `frames.csv`: one row per run and frame, in [`CSV_HEADER`]'s columns.
pub fn write_csv(results: &[FrameRun], path: &Path) -> Result<(), SimError> {
    let fail = |e: csv::Error| SimError::Run(format!("cannot write {}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    w.write_record(CSV_HEADER).map_err(fail)?;
    for r in results {
        let d = &r.draw;
        let mut rec = vec![r.run.to_string(), r.frame.name().to_owned()];
        rec.extend(
            d.euler
                .iter()
                .chain(&d.offset)
                .chain(&d.twist)
                .chain(&d.shift)
                .chain([&d.turn])
                .map(|x| num(*x)),
        );
        rec.push(r.converged.to_string());
        rec.push(r.settling_time.map(num).unwrap_or_default());
        for x in [
            r.effort,
            r.t_end,
            r.final_lyapunov,
            r.final_attitude_error,
            r.final_position_error,
        ] {
            rec.push(num(x));
        }
        rec.push(r.reason.clone().unwrap_or_default());
        w.write_record(&rec).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))
}

/// One frame over all runs.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameStats {
    /// The frame.
    pub frame: ErrorFrame,
    /// Runs flown.
    pub runs: usize,
    /// Runs that converged.
    pub converged: usize,
    /// Runs that settled.
    pub settled: usize,
    /// Median settling time over the settled runs (nearest rank).
    pub median_settling: Option<f64>,
    /// 90th percentile of the settling time over the settled runs (nearest rank).
    pub p90_settling: Option<f64>,
    /// Runs that flew the whole duration (did not stop).
    pub finished: usize,
    /// Mean effort over the finished runs.
    pub mean_effort: Option<f64>,
    /// Mean final L over the finished runs.
    pub mean_final_lyapunov: Option<f64>,
}

/// The `q`-quantile (0..1) of sorted `xs`, nearest rank.
fn quantile(xs: &[f64], q: f64) -> Option<f64> {
    let i = ((xs.len() as f64 * q).ceil() as usize).clamp(1, xs.len().max(1)) - 1;
    xs.get(i).copied()
}

/// The per-frame statistics.
pub fn stats(results: &[FrameRun], frames: &[ErrorFrame]) -> Vec<FrameStats> {
    frames
        .iter()
        .map(|frame| {
            let rs: Vec<&FrameRun> = results.iter().filter(|r| r.frame == *frame).collect();
            let mut settle: Vec<f64> = rs.iter().filter_map(|r| r.settling_time).collect();
            settle.sort_by(f64::total_cmp);
            let finished: Vec<&&FrameRun> = rs.iter().filter(|r| r.finished).collect();
            let mean = |f: fn(&FrameRun) -> f64| {
                (!finished.is_empty())
                    .then(|| finished.iter().map(|r| f(r)).sum::<f64>() / finished.len() as f64)
            };
            FrameStats {
                frame: *frame,
                runs: rs.len(),
                converged: rs.iter().filter(|r| r.converged).count(),
                settled: settle.len(),
                median_settling: quantile(&settle, 0.5),
                p90_settling: quantile(&settle, 0.9),
                finished: finished.len(),
                mean_effort: mean(|r| r.effort),
                mean_final_lyapunov: mean(|r| r.final_lyapunov),
            }
        })
        .collect()
}

fn opt(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "-".to_owned(), |v| format!("{v:.digits$}"))
}

fn opt_e(x: Option<f64>) -> String {
    x.map_or_else(|| "-".to_owned(), |v| format!("{v:.3e}"))
}

/// One line per frame, as printed.
pub fn summary_lines(stats: &[FrameStats]) -> String {
    let mut s = String::new();
    for f in stats {
        s += &format!(
            "{:<10} converged {}/{}, settled {} (median {} s, 90% {} s), finished {}, mean effort {}, mean final L {}\n",
            f.frame.name(),
            f.converged,
            f.runs,
            f.settled,
            opt(f.median_settling, 2),
            opt(f.p90_settling, 2),
            f.finished,
            opt(f.mean_effort, 2),
            opt_e(f.mean_final_lyapunov),
        );
    }
    s
}

/// How the study was drawn, for `table.md`'s heading.
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    /// The base scenario's name.
    pub scenario: String,
    /// The runs per frame.
    pub runs: usize,
    /// The seed.
    pub seed: u64,
    /// The duration flown (s).
    pub duration: f64,
    /// The world motions drawn.
    pub world: WorldMotion,
}

/// `table.md`: the per-frame table and the runs that did not converge.
pub fn table(setup: &Setup, stats: &[FrameStats], results: &[FrameRun]) -> String {
    let mut t = format!(
        "# error_frame Monte Carlo on `{}`\n\n{} runs per frame, seed {}, T = {} s. World motion: a translation uniform in a {} m ball and a turn about z uniform on [−{t}, {t}] rad. Converged: attitude error (geodesic angle of R_dᵀR) < {CONVERGED:e} rad and |x − x_d| < {CONVERGED:e} m at every step of the last {WINDOW} s. Settled: both below {SETTLED} to the end. Effort Σ‖τ_k‖h and final L (transported-error L) are means over the runs that flew the whole duration.\n\n",
        setup.scenario,
        setup.runs,
        setup.seed,
        setup.duration,
        setup.world.radius,
        t = setup.world.turn,
    );
    t += "| frame | converged | settled | median settling (s) | 90th pct settling (s) | finished | mean effort | mean final L |\n|---|---|---|---|---|---|---|---|\n";
    for f in stats {
        t += &format!(
            "| {} | {}/{} ({:.1} %) | {} | {} | {} | {} | {} | {} |\n",
            f.frame.name(),
            f.converged,
            f.runs,
            100.0 * f.converged as f64 / f.runs.max(1) as f64,
            f.settled,
            opt(f.median_settling, 2),
            opt(f.p90_settling, 2),
            f.finished,
            opt(f.mean_effort, 3),
            opt_e(f.mean_final_lyapunov),
        );
    }
    let failed: Vec<&FrameRun> = results.iter().filter(|r| !r.converged).collect();
    t += &format!("\n## Runs that did not converge ({})\n\n", failed.len());
    if failed.is_empty() {
        t += "None.\n";
        return t;
    }
    t += "| run | frame | Rz(a)Ry(b)Rx(c): a, b, c (rad) | position offset (m) | twist offset (ω, v) | world: t (m), ψ (rad) | reason |\n|---|---|---|---|---|---|---|\n";
    let list = |xs: &[f64], d: usize| {
        xs.iter()
            .map(|x| format!("{x:.d$}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for r in failed {
        let d = &r.draw;
        t += &format!(
            "| {} | {} | {} | {} | {} | ({}), {:.3} | {} |\n",
            r.run,
            r.frame.name(),
            list(&d.euler, 3),
            list(&d.offset, 3),
            list(&d.twist, 3),
            list(&d.shift, 1),
            d.turn,
            r.reason.as_deref().unwrap_or("").replace('|', "/"),
        );
    }
    t
}

/// Per frame, at each kept point: the mean over the runs still flying of each series
/// quantity (finite values only; NaN when no run is flying), and how many runs are still
/// flying.
#[derive(Debug, Clone, PartialEq)]
pub struct Mean {
    /// The means: attitude error, position error, `‖τ‖`, L.
    pub values: Vec<[f64; 4]>,
    /// Runs still flying.
    pub flying: Vec<usize>,
    /// Runs that stopped, and the latest time one stopped.
    pub stopped: (usize, f64),
}

/// The per-frame means, in run order (the same numbers for any thread count), every frame
/// over the longest series of all.
pub fn means(results: &[FrameRun], frames: &[ErrorFrame]) -> Vec<Mean> {
    let len = results.iter().map(|r| r.series.len()).max().unwrap_or(0);
    frames
        .iter()
        .map(|frame| {
            let runs: Vec<&FrameRun> = results.iter().filter(|r| r.frame == *frame).collect();
            let stopped = runs.iter().filter(|r| !r.finished);
            let mut mean = Mean {
                values: Vec::with_capacity(len),
                flying: Vec::with_capacity(len),
                stopped: (
                    stopped.clone().count(),
                    stopped.map(|r| r.t_end).fold(0.0, f64::max),
                ),
            };
            for j in 0..len {
                let (mut sum, mut count, mut flying) = ([0.0; 4], [0usize; 4], 0);
                for r in runs.iter().filter_map(|r| r.series.get(j)) {
                    flying += 1;
                    for q in 0..4 {
                        if r[q].is_finite() {
                            sum[q] += r[q];
                            count[q] += 1;
                        }
                    }
                }
                mean.values.push(std::array::from_fn(|q| match count[q] {
                    0 => f64::NAN,
                    n => sum[q] / n as f64,
                }));
                mean.flying.push(flying);
            }
            mean
        })
        .collect()
}

/// The colour of a frame in the figure.
pub fn frame_color(frame: ErrorFrame) -> plotters::style::RGBColor {
    law_color(match frame {
        ErrorFrame::Reference => "eqt",
        ErrorFrame::World => "gt",
        ErrorFrame::Recentred => "nog",
    })
}

/// The figure (`stem.png`, `stem.svg`): per frame, the means over the runs still flying of
/// the attitude error, the position error, `‖τ‖` and L (log10), and the runs still flying.
pub fn figure(
    means: &[Mean],
    frames: &[ErrorFrame],
    point_period: f64,
    setup: &Setup,
    stem: &Path,
) -> Result<(), SimError> {
    let titles = [
        ("Mean attitude error (angle of R_dᵀR), log10", "log10 rad"),
        ("Mean position error |x − x_d|, log10", "log10 m"),
        ("Mean ‖τ‖ (wrench), log10", "log10 ‖τ‖"),
        ("Mean L (transported error), log10", "log10 L"),
    ];
    // a frame whose runs stopped says so in its label (a run stopped after its first
    // step leaves a single point, which draws no line)
    let line = |(f, m): (&ErrorFrame, &Mean), points: Vec<(f64, f64)>| Line {
        label: match m.stopped {
            (0, _) => f.name().to_owned(),
            (n, t) => format!("{} ({n} stopped, all by t = {t} s)", f.name()),
        },
        color: frame_color(*f),
        points,
    };
    let mut panels: Vec<Panel> = titles
        .iter()
        .enumerate()
        .map(|(q, (title, y))| Panel {
            title: title.to_string(),
            y_label: y.to_string(),
            lines: frames
                .iter()
                .zip(means)
                .map(|(f, m)| {
                    let pts = m.values.iter().enumerate().filter_map(|(j, v)| {
                        let y = v[q].log10();
                        y.is_finite().then_some((j as f64 * point_period, y))
                    });
                    line((f, m), pts.collect())
                })
                .collect(),
        })
        .collect();
    panels.push(Panel {
        title: "Runs still flying".to_owned(),
        y_label: "runs".to_owned(),
        lines: frames
            .iter()
            .zip(means)
            .map(|(f, m)| {
                let pts = m.flying.iter().enumerate();
                line(
                    (f, m),
                    pts.map(|(j, n)| (j as f64 * point_period, *n as f64))
                        .collect(),
                )
            })
            .collect(),
    });
    render(
        stem,
        &format!(
            "error_frame on {}: {} runs per frame, world moved up to {} m",
            setup.scenario, setup.runs, setup.world.radius
        ),
        &panels,
        2,
        (1500, 1500),
    )
}

/// Writes the study's files into `out`: `frames.csv`, `table.md`, `frames.png`/`.svg`.
pub fn write(
    setup: &Setup,
    results: &[FrameRun],
    frames: &[ErrorFrame],
    control_period: f64,
    out: &Path,
) -> Result<Vec<FrameStats>, SimError> {
    write_csv(results, &out.join("frames.csv"))?;
    let stats = stats(results, frames);
    std::fs::write(out.join("table.md"), table(setup, &stats, results)).map_err(|e| {
        SimError::Run(format!(
            "cannot write {}: {e}",
            out.join("table.md").display()
        ))
    })?;
    let steps = (setup.duration / control_period).round() as u64;
    let point_period = series_stride(steps) as f64 * control_period;
    figure(
        &means(results, frames),
        frames,
        point_period,
        setup,
        &out.join("frames"),
    )?;
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_seeded_and_the_world_only_scales_its_own() {
        let a = draw(5, 3, WorldMotion::default());
        assert_eq!(a, draw(5, 3, WorldMotion::default()));
        let still = draw(
            5,
            3,
            WorldMotion {
                radius: 0.0,
                turn: 0.0,
            },
        );
        for (x, y) in a.iter().zip(&still) {
            assert_eq!((x.euler, x.offset, x.twist), (y.euler, y.offset, y.twist));
            assert_eq!((y.shift, y.turn), ([0.0; 3], 0.0));
            assert!(Vector3::from(x.shift).norm() <= 1e4);
            assert!(Vector3::from(x.offset).norm() <= POSITION_BALL);
            assert!(x.turn.abs() <= PI && x.euler.iter().all(|e| e.abs() <= PI));
        }
        assert_eq!(still[0].world(), Matrix4::identity());
        assert_ne!(a[0].euler, draw(1, 4, WorldMotion::default())[0].euler);
    }

    #[test]
    fn the_study_l_is_the_reference_law_s_own() {
        let s = Scenario::builtin("se3_circle").unwrap();
        let source = s.reference_source::<Se3, 4, 6>().unwrap();
        let d0 = source.desired();
        let draw = draw(1, 9, WorldMotion::default())[0];
        let (q, v) = draw.initial(&d0);
        let desired = Desired {
            q: draw.world() * d0.q,
            ..d0
        };
        let law = s.controller::<Se3, 4, 6>().unwrap();
        let output = law.compute(&q, &v, &desired).unwrap();
        let sample = Sample {
            t: 0.0,
            q,
            v,
            desired,
            output,
        };
        let m = metrics(&sample, law.config());
        assert_eq!(m[3], output.lyapunov.total);
        assert!((m[1] - Vector3::from(draw.offset).norm()).abs() < 1e-9);
        let r = euler_zyx(draw.euler[0], draw.euler[1], draw.euler[2]);
        let cos = ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        assert!(
            (m[0] - cos.acos()).abs() < 1e-6,
            "{} vs {}",
            m[0],
            cos.acos()
        );
    }

    #[test]
    fn quantiles_are_nearest_rank() {
        let xs = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0];
        assert_eq!(quantile(&xs, 0.5), Some(5.0));
        assert_eq!(quantile(&xs, 0.9), Some(9.0));
        assert_eq!(quantile(&[], 0.5), None);
    }
}
