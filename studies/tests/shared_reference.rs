//! The Monte Carlo study integrates its reference once and every run replays it: each run's
//! rows equal, bit for bit, those of the same run simulated with its own reference, with and
//! without sensors, for every law.

use eqtrack_controller::Law;
use eqtrack_controller::group::So3;
use eqtrack_controller::integrator::RigidBody;
use nalgebra::{SMatrix, SVector};
use plant::trajectory::simulate_with;
use scenario::Scenario;
use studies::montecarlo::{
    Sample, draw_samples, fly_against, initial_state, reference_table, run_sensors,
};

fn direct(s: &Scenario, sample: Sample) -> plant::trajectory::SimulatedTrajectory {
    let (r0, w0) = initial_state(s, sample);
    let plant = RigidBody::<f64, So3, 3, 3>::new(
        SMatrix::from_row_slice(&s.plant_inertia),
        r0,
        SVector::from(w0),
    )
    .unwrap();
    simulate_with::<So3, 3, 3>(s, plant, &|_| Ok(())).unwrap()
}

#[test]
fn every_run_against_the_shared_reference_equals_its_own_simulation() {
    for name in ["montecarlo", "sensors_so3"] {
        let mut base = pair_tests::load_scenario(name);
        base.duration = 3.0;
        let table = reference_table(&base).unwrap();
        assert_eq!(
            table.len() as u64,
            base.steps() + 1,
            "{name}: one entry per t_k"
        );
        for (run, sample) in draw_samples(3, 7).into_iter().enumerate() {
            for law in [Law::Eqt, Law::Gt, Law::Nog, Law::Asym] {
                let mut s = base.clone();
                s.law = law;
                run_sensors(&mut s, run);
                let shared = fly_against(&s, &table, run, sample).unwrap();
                let own = direct(&s, sample);
                assert_eq!(shared.rows.len(), own.rows.len());
                for (k, (a, b)) in shared.rows.iter().zip(&own.rows).enumerate() {
                    // Row's PartialEq compares every float; NaN-free rows here
                    assert_eq!(a, b, "{name}, run {run}, law {}: row {k}", law.name());
                }
            }
        }
    }
}
