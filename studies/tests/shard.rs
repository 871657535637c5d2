//! `shard.bin` read back: a written shard reads back bit for bit; every truncation, every
//! flipped byte and an absurd count is refused or read, never a panic, never an allocation
//! the file cannot back.

use eqtrack_controller::Law;
use studies::montecarlo::{RunResult, Sample};
use studies::shard::{SHARD_FILE, Shard, Study, read_shard, write_shard};

fn result(run: usize, law: Law) -> RunResult {
    RunResult {
        run,
        law,
        sample: Sample {
            r: [0.1, -0.2, 0.3],
            w: [1.0, f64::NAN, -3.0],
        },
        final_attitude_error: 1e-3,
        effort_0_5: 2.5,
        effort_0_20: 7.25,
        settling_time: run.is_multiple_of(2).then_some(4.5),
        series: (0..5).map(|k| [k as f64, 0.5, -0.25, 1e-300]).collect(),
    }
}

#[test]
fn a_shard_reads_back_and_damage_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let samples = vec![
        Sample {
            r: [0.0; 3],
            w: [0.0; 3]
        };
        5
    ];
    let study = Study::new(42, &samples, &[Law::Eqt, Law::Gt]);
    let shard: Shard = "1/2".parse().unwrap();
    let results: Vec<RunResult> = [1, 3]
        .iter()
        .flat_map(|r| [result(*r, Law::Eqt), result(*r, Law::Gt)])
        .collect();
    write_shard(dir.path(), shard, &study, &results).unwrap();
    let (s, st, back) = read_shard(dir.path()).unwrap();
    assert_eq!((s, &st), (shard, &study));
    assert_eq!(back.len(), results.len());
    for (a, b) in back.iter().zip(&results) {
        assert_eq!(
            (a.run, a.law, a.settling_time),
            (b.run, b.law, b.settling_time)
        );
        assert_eq!(a.sample.w[1].to_bits(), b.sample.w[1].to_bits());
        assert_eq!(a.series, b.series);
    }
    let good = std::fs::read(dir.path().join(SHARD_FILE)).unwrap();
    let path = dir.path().join(SHARD_FILE);
    for cut in 0..good.len() {
        std::fs::write(&path, &good[..cut]).unwrap();
        assert!(
            read_shard(dir.path()).is_err(),
            "cut at {cut} read as a shard"
        );
    }
    for at in 0..good.len() {
        let mut bad = good.clone();
        bad[at] ^= 0xff;
        std::fs::write(&path, &bad).unwrap();
        let _ = read_shard(dir.path()); // a value or an error, never a panic
    }
    // the result count set to 2^64 - 1: refused before anything is allocated for it
    let mut huge = good.clone();
    let count_at = 8 + 4 * 3 + 8 * 3 + 4 + 4 * 2;
    huge[count_at..count_at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(&path, &huge).unwrap();
    let e = read_shard(dir.path()).unwrap_err().to_string();
    assert!(e.contains("more than the file holds"), "{e}");
}
