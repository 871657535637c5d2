//! Runs the property kit on SO(3) × ℝ³, then flies the crate's scenario with eqtrack's law;
//! exits 1 when the kit fails or the flight does not converge.

use eqtrack_controller::kit::{check, sample};
use nalgebra::SVector;
use std::process::ExitCode;
use user_group::{So3xR3, fly, scenario};

fn main() -> ExitCode {
    // samples at moderate size, and some whose rotation is near the cut locus (angle π − δ)
    let samples: Vec<SVector<f64, 6>> = (0..24)
        .map(|i| {
            let mut v = sample::<6>(42, i, 1.5);
            if i % 2 == 1 {
                let n = v.fixed_rows::<3>(0).norm();
                let angle = std::f64::consts::PI - 1e-4;
                for k in 0..3 {
                    v[k] *= angle / n;
                }
            }
            v
        })
        .collect();
    match check::<So3xR3, 7, 6>(&samples, &scenario::config(), 42) {
        Ok(r) => println!(
            "kit: PASS ({} group checks, {} error-dynamics checks, {} Lyapunov checks)",
            r.group, r.error_dynamics, r.lyapunov
        ),
        Err(f) => {
            eprintln!("kit: FAIL: {f}");
            return ExitCode::FAILURE;
        }
    }
    let flight = match fly() {
        Ok(f) => f,
        Err(e) => {
            eprintln!("flight: refused: {e}");
            return ExitCode::FAILURE;
        }
    };
    println!(
        "flight: attitude error {:.3e} -> {:.3e}, position error {:.3e} m -> {:.3e} m over {} s; largest rise of L in a period {:.3e}",
        flight.first.0,
        flight.last.0,
        flight.first.1,
        flight.last.1,
        scenario::STEPS as f64 * scenario::PERIOD,
        flight.worst_rise
    );
    if flight.last.0 < 1e-3 * flight.first.0 && flight.last.1 < 1e-3 * flight.first.1 {
        println!("user_group: PASS");
        ExitCode::SUCCESS
    } else {
        eprintln!("user_group: FAIL: the flight did not converge to a thousandth of its start");
        ExitCode::FAILURE
    }
}
