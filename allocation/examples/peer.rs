//! eqtrack's allocation timed on the problems a peer solver is timed on (scripts/daqp.sh runs
//! DAQP on the same ones; docs/vehicles.md, "Bounded time"):
//!
//! ```text
//! cargo run --release -p eqtrack-allocation --example peer -- OUT_DIR
//! ```
//!
//! For the tilted hexarotor and the eight-thruster ROV: 200 seeded saturated demands, each
//! solved cold, and a 200-tick saturating trajectory, each tick warm-started from the last
//! answer. Writes `OUT_DIR/problems.csv` (the geometry, the bounds, each demand, the previous
//! command of a warm one, eqtrack's answers) and prints one JSON line per case: the median over
//! the problems of each problem's median time over 51 calls, for stage 1 alone (the torque)
//! and for the whole hierarchy.

use eqtrack_allocation::{Allocator, Commands, Geometry, Priority, presets};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

const PROBLEMS: usize = 200;
const CALLS: usize = 51;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The median time (ns) of `CALLS` calls of `f`.
fn time(mut f: impl FnMut()) -> f64 {
    median(
        (0..CALLS)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_nanos() as f64
            })
            .collect(),
    )
}

fn list(v: impl IntoIterator<Item = f64>) -> String {
    v.into_iter()
        .map(|x| format!("{x:e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn vehicle(
    name: &str,
    alloc: &Allocator<f64, 6>,
    rng: &mut ChaCha8Rng,
    csv: &mut String,
) -> Vec<String> {
    let g = alloc.geometry();
    let m = g.count();
    let bounds = alloc.bounds();
    let (lo, hi) = (bounds.lo, bounds.hi);
    let b = g.effectiveness();
    let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let mut demands = Vec::new();
    for _ in 0..PROBLEMS {
        let u = Commands::<f64>::from_fn(|j, _| {
            if j < m {
                lo[j] + (hi[j] - lo[j]) * unit()
            } else {
                0.0
            }
        });
        demands.push((g.wrench(&u) * (1.5 + 2.5 * unit()), None, false));
    }
    // the saturating trajectory, warm: each actuator swept through 1.6 times its range
    let mut previous: Option<Commands<f64>> = None;
    for k in 0..PROBLEMS {
        let t = k as f64 * 0.01;
        let u = Commands::<f64>::from_fn(|j, _| {
            if j >= m {
                return 0.0;
            }
            let (mid, half) = ((lo[j] + hi[j]) / 2.0, (hi[j] - lo[j]) / 2.0);
            mid + 1.6 * half * ((0.7 + 0.23 * j as f64) * t + j as f64).sin()
        });
        let d = g.wrench(&u);
        demands.push((d, previous, true));
        previous = Some(alloc.allocate_from(&d, &bounds, previous.as_ref()).u);
    }
    let mut times = [[Vec::new(), Vec::new()], [Vec::new(), Vec::new()]];
    for (i, (d, prev, along)) in demands.iter().enumerate() {
        let warm = usize::from(*along);
        let first = alloc.allocate_first_stage(d, &bounds, prev.as_ref());
        let full = alloc.allocate_from(d, &bounds, prev.as_ref());
        times[warm][0].push(time(|| {
            black_box(alloc.allocate_first_stage(black_box(d), &bounds, prev.as_ref()));
        }));
        times[warm][1].push(time(|| {
            black_box(alloc.allocate_from(black_box(d), &bounds, prev.as_ref()));
        }));
        let _ = writeln!(
            csv,
            "{name},{i},{},{m},{},{},{},{},{},{},{},{},{}",
            ["cold", "warm"][warm],
            list((0..6).flat_map(|r| (0..m).map(move |j| b[(r, j)]))),
            list(lo.iter().take(m).copied()),
            list(hi.iter().take(m).copied()),
            list(d.iter().copied()),
            list(prev.unwrap_or_else(Commands::zeros).iter().take(m).copied()),
            list(first.u.iter().take(m).copied()),
            list(full.u.iter().take(m).copied()),
            full.iterations,
            first.iterations,
        );
    }
    let mut out = Vec::new();
    for (warm, start) in ["cold", "warm"].iter().enumerate() {
        for (stage, what) in ["first", "full"].iter().enumerate() {
            out.push(format!(
                "{{\"vehicle\": \"{name}\", \"what\": \"{what}\", \"start\": \"{start}\", \"median_ns\": {:.0}, \"problems\": {}}}",
                median(times[warm][stage].clone()),
                times[warm][stage].len()
            ));
        }
    }
    out
}

fn main() {
    let out = std::env::args().nth(1).unwrap_or_else(|| ".".to_owned());
    let hex = Allocator::new(
        Geometry::<f64, 6>::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0))
            .expect("the preset spans"),
        &[],
        &[],
        Priority::Torque,
    )
    .expect("default settings");
    let rov = Allocator::new(
        Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0))
            .expect("the preset spans"),
        &[],
        &[],
        Priority::Torque,
    )
    .expect("default settings");
    let mut rng = ChaCha8Rng::seed_from_u64(50);
    let mut csv = String::from(
        "vehicle,index,start,m,B,lo,hi,demand,previous,u_first,u,iterations,first_iterations\n",
    );
    let mut lines = vehicle("hexarotor", &hex, &mut rng, &mut csv);
    lines.extend(vehicle("rov", &rov, &mut rng, &mut csv));
    let path = std::path::Path::new(&out).join("problems.csv");
    if let Err(e) = std::fs::write(&path, csv) {
        eprintln!("peer: cannot write {}: {e}", path.display());
        std::process::exit(1);
    }
    for l in lines {
        println!("{l}");
    }
}
