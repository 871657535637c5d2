//! The C header `include/eqtrack_wire.h` describes the Rust structs exactly: a C program
//! compiled against it prints every struct's size and every field's offset and size, and
//! they must equal what Rust reports for `ipc_types::{StateMsg, CommandMsg, WireSegment,
//! PlanMsg, StatusMsg}`. Needs a C compiler (`cc`, which Rust's own linking already needs).

use ipc_types::{CommandMsg, PlanMsg, StateMsg, StatusMsg, WireSegment};
use std::collections::BTreeMap;
use std::mem::{offset_of, size_of, size_of_val};
use std::process::Command;

/// `(struct, field) -> (offset, size)`, and `(struct, "") -> (0, size of the struct)`.
type Layout = BTreeMap<(String, String), (usize, usize)>;

/// Records a struct's size and each listed field's offset and size.
macro_rules! fields {
    ($map:ident, $value:expr, $ty:ty, $cname:literal, [$($f:ident),* $(,)?]) => {{
        let v: $ty = $value;
        $map.insert(($cname.to_owned(), String::new()), (0, size_of::<$ty>()));
        $( $map.insert(
            ($cname.to_owned(), stringify!($f).to_owned()),
            (offset_of!($ty, $f), size_of_val(&v.$f)),
        ); )*
    }};
}

fn rust_layout() -> Layout {
    use ipc_types::WireGroup::So3;
    let mut m = Layout::new();
    fields!(
        m,
        StateMsg::new(So3),
        StateMsg,
        "eqtrack_StateMsg",
        [
            version,
            group,
            seq,
            t,
            control_period,
            stamp_ns,
            q,
            v,
            applied,
            flags,
            plant_pid,
            fingerprint,
            scenario,
            wheels,
            reserved_wheels,
            wheel_speeds,
        ]
    );
    fields!(
        m,
        CommandMsg::new(So3),
        CommandMsg,
        "eqtrack_CommandMsg",
        [
            version,
            group,
            seq,
            state_received_ns,
            stamp_ns,
            compute_ns,
            tau,
            lyapunov,
            observer,
            integral,
            previous_seq,
            estimate_before,
            z_before,
            heap_allocations,
            flags,
            mismatch,
            fingerprint,
            expected_period,
            scenario,
            law,
            plans_received,
            plan_seq,
            plan_pid,
            failsafe,
            actuators,
            alloc_status,
            demand,
            achieved,
            accounted,
            u_previous,
            u_cmd,
            detected,
            detected_kind,
            detected_value,
            detected_refined,
            alarms,
            statistic,
            suspect,
            reserved_detector,
        ]
    );
    fields!(
        m,
        PlanMsg::new(So3).segments[0],
        WireSegment,
        "eqtrack_WireSegment",
        [t0, t1, shape, reserved, start, twists,]
    );
    fields!(
        m,
        PlanMsg::new(So3),
        PlanMsg,
        "eqtrack_PlanMsg",
        [
            version,
            group,
            seq,
            stamp_ns,
            first_index,
            count,
            planner_pid,
            reserved,
            segments,
        ]
    );
    fields!(
        m,
        StatusMsg::new(So3, ""),
        StatusMsg,
        "eqtrack_StatusMsg",
        [
            version,
            group,
            seq,
            stamp_ns,
            cycle,
            t,
            target_rate_hz,
            rate_hz,
            rtt_p50_ns,
            rtt_p99_ns,
            rtt_max_ns,
            misses,
            safe_mode_entries,
            lyapunov,
            last_command_ns,
            flags,
            plant_pid,
            scenario,
            detections,
            last_detected,
            last_detected_kind,
            alarms,
            last_detected_value,
            failsafe,
            failsafe_transitions,
        ]
    );
    fields!(
        m,
        ipc_types::Gains::ZERO,
        ipc_types::Gains,
        "eqtrack_Gains",
        [cycle, k, kd, observer, ki, c]
    );
    fields!(
        m,
        ipc_types::ParamMsg::new(So3, 0, ipc_types::Gains::ZERO),
        ipc_types::ParamMsg,
        "eqtrack_ParamMsg",
        [
            version,
            group,
            seq,
            stamp_ns,
            fingerprint,
            current,
            previous
        ]
    );
    m
}

/// The same table from C: a program that includes the header prints `struct field offset size`.
fn c_layout(rust: &Layout) -> Layout {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut prog =
        String::from("#include <stdio.h>\n#include \"eqtrack_wire.h\"\nint main(void) {\n");
    for (s, f) in rust.keys() {
        if f.is_empty() {
            prog += &format!("  printf(\"{s} - 0 %zu\\n\", sizeof({s}));\n");
        } else {
            prog += &format!(
                "  printf(\"{s} {f} %zu %zu\\n\", offsetof({s}, {f}), sizeof((({s} *)0)->{f}));\n"
            );
        }
    }
    prog += "  return 0;\n}\n";
    let (src, exe) = (dir.join("layout.c"), dir.join("layout"));
    std::fs::write(&src, prog).unwrap();
    let include = concat!(env!("CARGO_MANIFEST_DIR"), "/include");
    let out = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Werror", "-I", include, "-o"])
        .arg(&exe)
        .arg(&src)
        .output()
        .expect("a C compiler (cc) is needed to check the header");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = Command::new(&exe).output().unwrap();
    String::from_utf8(run.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let field = if w[1] == "-" {
                String::new()
            } else {
                w[1].to_owned()
            };
            (
                (w[0].to_owned(), field),
                (w[2].parse().unwrap(), w[3].parse().unwrap()),
            )
        })
        .collect()
}

#[test]
fn the_c_header_has_the_rust_layout() {
    let rust = rust_layout();
    let c = c_layout(&rust);
    assert_eq!(c.len(), rust.len());
    for (key, r) in &rust {
        assert_eq!(
            c.get(key),
            Some(r),
            "{key:?}: C (offset, size) differs from Rust's"
        );
    }
    // every field is listed: the fields fill their struct (up to a little padding)
    for s in [
        "eqtrack_StateMsg",
        "eqtrack_CommandMsg",
        "eqtrack_WireSegment",
        "eqtrack_PlanMsg",
        "eqtrack_StatusMsg",
        "eqtrack_Gains",
        "eqtrack_ParamMsg",
    ] {
        let total = rust[&(s.to_owned(), String::new())].1;
        let fields: usize = rust
            .iter()
            .filter(|((n, f), _)| n == s && !f.is_empty())
            .map(|(_, v)| v.1)
            .sum();
        assert!(
            fields <= total && total - fields < 8,
            "{s}: fields {fields} of {total} bytes"
        );
    }
}

#[test]
fn the_header_names_the_protocol_version_and_limits() {
    use ipc_types::WireGroup::{Se2, Se3, So3};
    let h = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/include/eqtrack_wire.h"
    ))
    .unwrap();
    for (name, value) in [
        (
            "EQTRACK_PROTOCOL_VERSION",
            format!("{}u", ipc_types::PROTOCOL_VERSION),
        ),
        ("EQTRACK_MAX_N", ipc_types::MAX_N.to_string()),
        ("EQTRACK_MAX_M", ipc_types::MAX_M.to_string()),
        ("EQTRACK_NAME_BYTES", ipc_types::NAME_BYTES.to_string()),
        ("EQTRACK_PLAN_WINDOW", ipc_types::PLAN_WINDOW.to_string()),
        (
            "EQTRACK_MAX_ACTUATORS",
            ipc_types::MAX_ACTUATORS.to_string(),
        ),
        (
            "EQTRACK_SHAPE_REST",
            format!("{}u", ipc_types::plan::SHAPE_REST),
        ),
        (
            "EQTRACK_SHAPE_THROUGH",
            format!("{}u", ipc_types::plan::SHAPE_THROUGH),
        ),
        ("EQTRACK_GROUP_SO3", format!("{}u", So3.code())),
        ("EQTRACK_GROUP_SE3", format!("{}u", Se3.code())),
        ("EQTRACK_GROUP_SE2", format!("{}u", Se2.code())),
        (
            "EQTRACK_FLAG_WAKE_EVENT",
            format!("{}u", ipc_types::flags::WAKE_EVENT),
        ),
        (
            "EQTRACK_FLAG_SHUTDOWN",
            format!("{}u", ipc_types::flags::SHUTDOWN),
        ),
        (
            "EQTRACK_FLAG_REFUSED",
            format!("{}u", ipc_types::flags::REFUSED),
        ),
        (
            "EQTRACK_FLAG_STREAMED",
            format!("{}u", ipc_types::flags::STREAMED),
        ),
        (
            "EQTRACK_FLAG_DETECTING",
            format!("{}u", ipc_types::flags::DETECTING),
        ),
        (
            "EQTRACK_STATUS_SAFE_MODE",
            format!("{}u", ipc_types::status_flags::SAFE_MODE),
        ),
        (
            "EQTRACK_STATUS_ENDED",
            format!("{}u", ipc_types::status_flags::ENDED),
        ),
        (
            "EQTRACK_STATUS_REALTIME",
            format!("{}u", ipc_types::status_flags::REALTIME),
        ),
        (
            "EQTRACK_STATUS_DETECTING",
            format!("{}u", ipc_types::status_flags::DETECTING),
        ),
    ] {
        let line = format!("#define {name} {value}");
        assert!(
            h.lines().any(|l| l.starts_with(&line)),
            "the header lacks `{line}`"
        );
    }
}
