/*
 * eqtrack_wire.h: the wire layout of eqtrack's messages, for C and C++ tools and for
 * Python ctypes. The Rust structs are `ipc_types::{StateMsg, CommandMsg, WireSegment,
 * PlanMsg, StatusMsg, Gains, ParamMsg}` (#[repr(C)]); `ipc_types/tests/c_header.rs` compiles this header and checks
 * every size and field offset against them. docs/wire.md explains the fields and how to
 * attach to a running pair.
 *
 * Each message sits in an iceoryx2 blackboard entry (key type uint32_t, keys 0..7 are the
 * writer slots) of the service `eqtrack/<run>/state`, `eqtrack/<run>/command` or
 * `eqtrack/<run>/plan` or `eqtrack/<run>/status`; iceoryx2 type names "eqtrack::StateMsg7",
 * "eqtrack::CommandMsg9", "eqtrack::PlanMsg4", "eqtrack::StatusMsg6". All numbers are little-endian on the machines eqtrack runs on.
 */
#ifndef EQTRACK_WIRE_H
#define EQTRACK_WIRE_H

#include <stddef.h>
#include <stdint.h>

#define EQTRACK_PROTOCOL_VERSION 10u
#define EQTRACK_MAX_N 4        /* configuration matrices are n x n, n <= 4 */
#define EQTRACK_MAX_M 6        /* algebra dimension m <= 6 */
#define EQTRACK_NAME_BYTES 32  /* scenario name, UTF-8, NUL-padded */
#define EQTRACK_PLAN_WINDOW 8  /* segments per plan message */
#define EQTRACK_MAX_ACTUATORS 12 /* actuator commands in a vehicle's command */
#define EQTRACK_MAX_WHEELS 6     /* reaction-wheel speeds in a state */

/* group codes */
#define EQTRACK_GROUP_SO3 1u
#define EQTRACK_GROUP_SE3 2u
#define EQTRACK_GROUP_SE2 3u

/* StateMsg.flags and CommandMsg.flags */
#define EQTRACK_FLAG_WAKE_EVENT 1u
#define EQTRACK_FLAG_SHUTDOWN 2u
#define EQTRACK_FLAG_REFUSED 4u
#define EQTRACK_FLAG_STREAMED 8u  /* CommandMsg: the controller tracks a streamed reference */
#define EQTRACK_FLAG_TUNABLE 16u  /* StateMsg: the run's gains may change: read eqtrack/<run>/params */
#define EQTRACK_FLAG_TUNED 32u    /* CommandMsg: answered with the params board's gains for the state */
#define EQTRACK_FLAG_DETECTING 64u /* CommandMsg: the controller runs the failure detector */
#define EQTRACK_FLAG_ESTIMATE_DEGRADED 128u /* StateMsg: the gated estimator's health is degraded */
#define EQTRACK_FLAG_ESTIMATE_LOST 256u     /* StateMsg: the gated estimator's health is lost */
#define EQTRACK_FLAG_SUPERVISED 512u  /* CommandMsg: the controller runs the failsafe manager */

/* the plant's state at t_k */
typedef struct eqtrack_StateMsg {
    uint32_t version;       /* EQTRACK_PROTOCOL_VERSION; 0: slot never written */
    uint32_t group;         /* EQTRACK_GROUP_* */
    uint64_t seq;           /* control step k */
    double t;               /* t_k = k * control_period, s */
    double control_period;  /* s */
    uint64_t stamp_ns;      /* CLOCK_MONOTONIC at publication */
    double q[EQTRACK_MAX_N * EQTRACK_MAX_N]; /* Q, row-major n x n in the first n*n */
    double v[EQTRACK_MAX_M]; /* body velocity V, first m (SE(3): omega then v) */
    double applied[EQTRACK_MAX_M]; /* torque applied over [t_{k-1}, t_k), first m; 0 at k = 0 */
    uint32_t flags;         /* EQTRACK_FLAG_* */
    uint32_t plant_pid;
    uint64_t fingerprint;   /* scenario fingerprint, 0: none */
    uint8_t scenario[EQTRACK_NAME_BYTES];
    uint32_t wheels;        /* reaction wheels carried, <= EQTRACK_MAX_WHEELS */
    uint32_t reserved_wheels; /* 0 */
    double wheel_speeds[EQTRACK_MAX_WHEELS]; /* rad/s relative to the body, first `wheels` */
} eqtrack_StateMsg;

/* the controller's answer to state k */
typedef struct eqtrack_CommandMsg {
    uint32_t version;
    uint32_t group;
    uint64_t seq;               /* the state's k */
    uint64_t state_received_ns; /* CLOCK_MONOTONIC when the state was received */
    uint64_t stamp_ns;          /* CLOCK_MONOTONIC at publication */
    uint64_t compute_ns;        /* state received -> command published */
    double tau[EQTRACK_MAX_M];  /* torque after saturation, first m */
    double lyapunov;            /* L at t_k */
    double observer[EQTRACK_MAX_M]; /* disturbance estimate d_hat (body), subtracted; 0: none */
    double integral[EQTRACK_MAX_M]; /* integral torque -K_I z (body), added; 0: none */
    uint64_t previous_seq;      /* the state processed before this one; UINT64_MAX: none */
    double estimate_before[EQTRACK_MAX_M]; /* observer estimate before this update (its frame) */
    double z_before[EQTRACK_MAX_M];        /* integral z before this update */
    uint64_t heap_allocations;  /* since the controller's first cycle */
    uint32_t flags;             /* EQTRACK_FLAG_REFUSED, EQTRACK_FLAG_STREAMED */
    uint32_t mismatch;          /* with REFUSED: what differs (1 group, 2 period, 4 scenario) */
    uint64_t fingerprint;
    double expected_period;     /* 0: the controller follows the plant */
    uint8_t scenario[EQTRACK_NAME_BYTES];
    uint32_t law;               /* 1 eqt, 2 gt, 3 nog, 4 asym; 0: not said */
    uint32_t plans_received;    /* streamed reference: plan messages taken before this answer */
    uint64_t plan_seq;          /* the last of them: its seq (0: none) */
    uint32_t plan_pid;          /* and its planner's pid (0: none) */
    uint32_t failsafe;          /* failsafe manager: action code bits 0-3 (0 nominal), cause code
                                   bits 4-7, raised causes bits 8-11 (link..tracking) */
    uint32_t actuators;         /* a vehicle's actuator count; 0: no vehicle, tau is applied */
    uint32_t alloc_status;      /* 0 met, 1 torque not reachable, 2 force given up, 3 cap, 4 bad demand */
    double demand[EQTRACK_MAX_M];    /* tau less the known restoring wrench, first m */
    double achieved[EQTRACK_MAX_M];  /* B u_cmd, first m */
    double accounted[EQTRACK_MAX_M]; /* B u_cmd plus the compensated restoring wrench: the next
                                        state's `applied` when this command is applied */
    double u_previous[EQTRACK_MAX_ACTUATORS]; /* the command the rate limit narrowed around */
    double u_cmd[EQTRACK_MAX_ACTUATORS];      /* actuator commands, first `actuators` */
    uint32_t detected;          /* failure detector: the actuator found this cycle plus one; 0: none */
    uint32_t detected_kind;     /* 1 dead, 2 stuck, 3 effectiveness; 0: none */
    double detected_value;      /* the stuck value or factor told to the allocator (0 when dead) */
    uint32_t detected_refined;  /* 1: refines an earlier finding of the same actuator */
    uint32_t alarms;            /* the detector's alarms so far */
    double statistic;           /* the best hypothesis's statistic at its last test (0: none yet) */
    uint32_t suspect;           /* that hypothesis's actuator plus one (0: no test yet) */
    uint32_t reserved_detector;
} eqtrack_CommandMsg;

/* eqtrack_WireSegment.shape */
#define EQTRACK_SHAPE_REST 0u    /* geodesic from `start` by twists[0..m], quintic timing */
#define EQTRACK_SHAPE_THROUGH 1u /* quintic Hermite: start * prod_j exp(B_j(s) v_j) */

/* one piece of a streamed path */
typedef struct eqtrack_WireSegment {
    double t0;
    double t1;
    uint32_t shape;                              /* EQTRACK_SHAPE_REST or _THROUGH */
    uint32_t reserved;
    double start[EQTRACK_MAX_N * EQTRACK_MAX_N]; /* row-major n x n */
    double twists[5 * EQTRACK_MAX_M];            /* REST: log(Q_start^-1 Q_end), first m;
                                                    THROUGH: v_1..v_5 at k * EQTRACK_MAX_M */
} eqtrack_WireSegment;

/* a window of consecutive segments from a planner */
typedef struct eqtrack_PlanMsg {
    uint32_t version;
    uint32_t group;
    uint64_t seq;
    uint64_t stamp_ns;
    uint32_t first_index;
    uint32_t count;           /* segments used, <= EQTRACK_PLAN_WINDOW */
    uint32_t planner_pid;
    uint32_t reserved;
    eqtrack_WireSegment segments[EQTRACK_PLAN_WINDOW];
} eqtrack_PlanMsg;

/* StatusMsg.flags */
#define EQTRACK_STATUS_SAFE_MODE 1u
#define EQTRACK_STATUS_ENDED 2u
#define EQTRACK_STATUS_REALTIME 4u
#define EQTRACK_STATUS_DETECTING 8u /* the controller runs the failure detector */

/* a run's live figures, from the plant's flight recorder, about 20 times a second */
typedef struct eqtrack_StatusMsg {
    uint32_t version;
    uint32_t group;
    uint64_t seq;
    uint64_t stamp_ns;
    uint64_t cycle;             /* newest cycle k recorded */
    double t;                   /* its t_k, s */
    double target_rate_hz;      /* 0: lockstep */
    double rate_hz;             /* cycles in the last second, counted */
    uint64_t rtt_p50_ns;        /* round trip over the last second */
    uint64_t rtt_p99_ns;
    uint64_t rtt_max_ns;
    uint64_t misses;            /* deadline misses since the start */
    uint64_t safe_mode_entries;
    double lyapunov;            /* of the newest command; NaN: none yet */
    uint64_t last_command_ns;   /* CLOCK_MONOTONIC of the newest command; 0: none */
    uint32_t flags;             /* EQTRACK_STATUS_* */
    uint32_t plant_pid;
    uint8_t scenario[EQTRACK_NAME_BYTES];
    uint32_t detections;         /* failures the controller's detector found so far */
    uint32_t last_detected;      /* the newest one's actuator plus one; 0: none */
    uint32_t last_detected_kind; /* 1 dead, 2 stuck, 3 effectiveness; 0: none */
    uint32_t alarms;             /* the detector's alarms so far */
    double last_detected_value;  /* the newest one's stuck value or factor */
    uint32_t failsafe;           /* the failsafe word of the newest command (0: nominal) */
    uint32_t failsafe_transitions; /* the failsafe's transitions so far */
} eqtrack_StatusMsg;

/* run-time parameters (plant_sim run --tunable): the controller's gains from one cycle on */
typedef struct eqtrack_Gains {
    uint64_t cycle;                                 /* the first cycle they answer */
    double k[EQTRACK_MAX_N * EQTRACK_MAX_N];        /* K, n x n row-major */
    double kd[EQTRACK_MAX_M * EQTRACK_MAX_M];       /* K_d, m x m row-major */
    double observer[EQTRACK_MAX_M];                 /* the disturbance observer's L (0: none) */
    double ki[EQTRACK_MAX_M];                       /* the integral's K_I (0: none) */
    double c[EQTRACK_MAX_M];                        /* the integral's c (0: none) */
} eqtrack_Gains;

/* the eqtrack/<run>/params board ("eqtrack::ParamMsg1"), written by the plant */
typedef struct eqtrack_ParamMsg {
    uint32_t version;       /* EQTRACK_PROTOCOL_VERSION; 0: never written */
    uint32_t group;
    uint64_t seq;           /* changes so far */
    uint64_t stamp_ns;
    uint64_t fingerprint;   /* the run's scenario fingerprint */
    eqtrack_Gains current;  /* in force from current.cycle on */
    eqtrack_Gains previous; /* before that */
} eqtrack_ParamMsg;

#endif /* EQTRACK_WIRE_H */
