//! Plan messages and their segments through the wire: the conversions of `link::wire` and
//! the checks of `ipc_types::plan`, on both groups.

use eqtrack_controller::path::Segment;
use ipc_types::plan::*;
use ipc_types::{MAX_M, WireGroup};
use link::wire::{segment, wire_segment};

use eqtrack_controller::group::{MatrixLieGroup, Se2, Se3, So3};
use nalgebra::{Matrix3, Vector3, Vector6};

fn so3_segment(t0: f64, t1: f64) -> Segment<f64, 3, 3> {
    let a = So3::exp(&Vector3::new(0.3, -1.0, 2.0));
    let b = So3::exp(&Vector3::new(-2.5, 0.4, 0.1));
    Segment::between::<So3>(t0, &a, t1, &b)
}

#[test]
fn segments_cross_the_wire_unchanged_on_both_groups() {
    let s = so3_segment(1.0, 2.5);
    assert_eq!(segment::<3, 3>(&wire_segment(&s)), s);
    let a = Se3::exp(&Vector6::new(0.1, 0.2, -3.0, 1.0, 2.0, 3.0));
    let b = Se3::exp(&Vector6::new(2.0, -0.2, 0.3, -1.0, 0.5, 0.0));
    let s = Segment::between::<Se3>(0.0, &a, 4.0, &b);
    assert_eq!(segment::<4, 6>(&wire_segment(&s)), s);
    // through-waypoint pieces too
    let knot = |q, v: Vector6<f64>| eqtrack_controller::PathSample {
        q,
        v,
        v_dot: v * 0.5,
    };
    let s = Segment::hermite::<Se3>(
        0.0,
        &knot(a, Vector6::new(0.1, 0.2, 0.3, 0.4, 0.5, 0.6)),
        4.0,
        &knot(b, Vector6::new(-0.3, 0.2, 0.1, 0.0, 0.5, -0.6)),
    );
    let w = wire_segment(&s);
    assert_eq!(w.shape, SHAPE_THROUGH);
    assert_eq!(segment::<4, 6>(&w), s);
    let t = So3::exp(&Vector3::new(0.3, 0.0, 0.1));
    let s = Segment::hermite::<So3>(
        1.0,
        &eqtrack_controller::PathSample::rest(t),
        2.0,
        &knot3(t),
    );
    assert_eq!(segment::<3, 3>(&wire_segment(&s)), s);
}

fn knot3(q: Matrix3<f64>) -> eqtrack_controller::PathSample<f64, 3, 3> {
    eqtrack_controller::PathSample {
        q: q * So3::exp(&Vector3::new(0.0, 1.0, 0.0)),
        v: Vector3::new(0.5, -0.1, 0.0),
        v_dot: Vector3::new(0.0, 0.2, 0.1),
    }
}

#[test]
fn plan_messages_round_trip_through_their_bytes() {
    let mut m = PlanMsg::new(WireGroup::So3);
    m.seq = 12;
    m.stamp_ns = 34;
    m.planner_pid = 56;
    m.first_index = 2;
    m.count = 1;
    m.segments[0] = wire_segment(&so3_segment(0.5, 1.5));
    m.segments[3].twists[29] = f64::NAN;
    let b = m.to_bytes();
    let back = PlanMsg::from_bytes(&b).unwrap();
    assert_eq!(back.to_bytes(), b);
    assert_eq!(
        (back.seq, back.planner_pid, back.segments[0]),
        (12, 56, m.segments[0])
    );
    assert!(back.segments[3].twists[29].is_nan());
    assert!(PlanMsg::from_bytes(&b[1..]).is_err());
}

#[test]
fn plans_are_checked() {
    let mut p = PlanMsg::new(WireGroup::So3);
    p.count = 2;
    p.segments[0] = wire_segment(&so3_segment(0.0, 1.0));
    p.segments[1] = wire_segment(&so3_segment(1.0, 2.0));
    assert_eq!(check_plan(&p, WireGroup::So3, 0.01), Ok(()));
    assert_eq!(
        check_plan(&p, WireGroup::Se3, 0.01),
        Err(PlanInvalid::Group)
    );
    // a leg shorter than the control period, or a period that is not a number
    assert_eq!(check_plan(&p, WireGroup::So3, 1.0), Ok(()));
    assert_eq!(
        check_plan(&p, WireGroup::So3, 1.0 + 1e-9),
        Err(PlanInvalid::ShortLeg)
    );
    assert_eq!(
        check_plan(&p, WireGroup::So3, f64::NAN),
        Err(PlanInvalid::ShortLeg)
    );
    let bad = |f: &dyn Fn(&mut PlanMsg)| {
        let mut q = p;
        f(&mut q);
        check_plan(&q, WireGroup::So3, 0.01)
    };
    assert_eq!(bad(&|q| q.segments[1].shape = 2), Err(PlanInvalid::Shape));
    // a through piece's later twists are checked, a rest piece's are not used
    assert_eq!(
        bad(&|q| {
            q.segments[1].shape = SHAPE_THROUGH;
            q.segments[1].twists[4 * MAX_M + 2] = f64::NAN
        }),
        Err(PlanInvalid::NonFinite)
    );
    assert_eq!(
        bad(&|q| q.segments[1].twists[4 * MAX_M + 2] = f64::NAN),
        Ok(())
    );
    assert_eq!(bad(&|q| q.version = 0), Err(PlanInvalid::Version));
    assert_eq!(bad(&|q| q.count = 9), Err(PlanInvalid::Count));
    assert_eq!(
        bad(&|q| q.segments[1].twists[2] = f64::NAN),
        Err(PlanInvalid::NonFinite)
    );
    assert_eq!(bad(&|q| q.segments[1].t0 = 0.5), Err(PlanInvalid::Times));
    assert_eq!(bad(&|q| q.segments[0].t1 = 0.0), Err(PlanInvalid::Times));
    assert_eq!(
        bad(&|q| q.segments[1].start[0] *= 1.001),
        Err(PlanInvalid::NotOnGroup)
    );
    // a reflection is orthonormal but not a rotation
    let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
    let mut s = so3_segment(1.0, 2.0);
    s.start = flip;
    assert_eq!(
        bad(&|q| q.segments[1] = wire_segment(&s)),
        Err(PlanInvalid::NotOnGroup)
    );
    // unused entries are not looked at
    assert_eq!(bad(&|q| q.segments[5].t0 = f64::NAN), Ok(()));
    // SE(3): the last row must be 0 0 0 1
    let mut p = PlanMsg::new(WireGroup::Se3);
    p.count = 1;
    let a = Se3::exp(&Vector6::new(0.1, 0.2, -3.0, 1.0, 2.0, 3.0));
    p.segments[0] = wire_segment(&Segment::between::<Se3>(0.0, &a, 1.0, &a));
    assert_eq!(check_plan(&p, WireGroup::Se3, 0.01), Ok(()));
    p.segments[0].start[14] = 0.5;
    assert_eq!(
        check_plan(&p, WireGroup::Se3, 0.01),
        Err(PlanInvalid::NotOnGroup)
    );
}

/// SE(2): a planar pose far from the origin is on the group (its third column is the
/// position, not a rotation's); a scaled rotation block, a reflection or a wrong last row is
/// not. On SO(3) the same matrix is refused.
#[test]
fn planar_plans_are_checked_on_se2() {
    let mut p = PlanMsg::new(WireGroup::Se2);
    p.count = 1;
    let a = Se2::exp(&Vector3::new(2.5, 300.0, -40.0));
    let b = Se2::exp(&Vector3::new(-1.0, 2.0, 1.0));
    let s = Segment::between::<Se2>(0.0, &a, 1.0, &b);
    assert_eq!(segment::<3, 3>(&wire_segment(&s)), s);
    p.segments[0] = wire_segment(&s);
    assert_eq!(check_plan(&p, WireGroup::Se2, 0.01), Ok(()));
    let mut so3 = p;
    so3.group = WireGroup::So3.code();
    assert_eq!(
        check_plan(&so3, WireGroup::So3, 0.01),
        Err(PlanInvalid::NotOnGroup)
    );
    let bad = |f: &dyn Fn(&mut PlanMsg)| {
        let mut q = p;
        f(&mut q);
        check_plan(&q, WireGroup::Se2, 0.01)
    };
    assert_eq!(
        bad(&|q| q.segments[0].start[0] *= 1.001),
        Err(PlanInvalid::NotOnGroup)
    );
    assert_eq!(
        bad(&|q| q.segments[0].start[7] = 0.5),
        Err(PlanInvalid::NotOnGroup)
    );
    assert_eq!(
        bad(&|q| q.segments[0].start[8] = 1.5),
        Err(PlanInvalid::NotOnGroup)
    );
    // the planar reflection diag(1, −1)
    assert_eq!(
        bad(&|q| {
            q.segments[0].start[..9]
                .copy_from_slice(&[1.0, 0.0, 3.0, 0.0, -1.0, 4.0, 0.0, 0.0, 1.0])
        }),
        Err(PlanInvalid::NotOnGroup)
    );
}
