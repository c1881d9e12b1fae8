//! The staged process example `examples/underfill-cure-cycles.json`: cure, cool-down and
//! thermal cycles of the underfill-cure section in one run and one store.

mod common;

use common::{example, mpm, text};
use mpm_io::ResultStore;

/// In-plane von Mises stress of every particle of a frame of 2×2 stresses.
fn von_mises(stress: &[f64]) -> Vec<f64> {
    stress
        .chunks_exact(4)
        .map(|s| {
            let (xx, xy, yy) = (s[0], s[1], s[3]);
            (xx * xx - xx * yy + yy * yy + 3.0 * xy * xy).sqrt()
        })
        .collect()
}

fn peak(store: &ResultStore, frame: u64) -> f64 {
    let (_, s) = store.frame("stress", frame).unwrap();
    von_mises(&s).into_iter().fold(0.0, f64::max)
}

#[test]
fn cure_cool_and_cycles_run_as_one_chain() {
    let dir = tempfile::tempdir().unwrap();
    let staged = example("underfill-cure-cycles.json");
    let out = mpm(
        &["run", staged.to_str().unwrap(), "--out", "r", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let unstaged = example("underfill-cure.json");
    let out = mpm(
        &["run", unstaged.to_str().unwrap(), "--out", "r", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let path = dir.path().join("r/underfill-cure-cycles.zarr");
    let whole = ResultStore::open(dir.path().join("r/underfill-cure.zarr")).unwrap();

    // The stages `cure` and `cool` are the one-stage underfill-cure run (same steps, same
    // frame times: 150 s apart), bit for bit, across the hand-over at 2100 s.
    for (stage, offset) in [("cure", 0u64), ("cool", 14)] {
        let s = ResultStore::open_stage(&path, Some(stage)).unwrap();
        for frame in 0..s.frame_count().unwrap() {
            for field in ["x", "stress", "temperature", "cure"] {
                assert_eq!(
                    s.frame(field, frame).unwrap(),
                    whole.frame(field, frame + offset).unwrap(),
                    "{stage} frame {frame}: {field}"
                );
            }
        }
    }

    // The cycles start from the cool-down's residual stress and temperature.
    let cool = ResultStore::open_stage(&path, Some("cool")).unwrap();
    let cycles = ResultStore::open_stage(&path, Some("cycles")).unwrap();
    let last_cool = cool.frame_count().unwrap() - 1;
    assert_eq!(
        cycles.frame("stress", 0).unwrap(),
        cool.frame("stress", last_cool).unwrap()
    );
    let residual = peak(&cool, last_cool);
    // Frames every 300 s; each cycle is 3600 s: the cold dwell (233 K) ends at frame
    // 12·k, the hot dwell (398 K) at 12·k − 6.
    let cold: Vec<f64> = (1..=3).map(|k| peak(&cycles, 12 * k)).collect();
    let hot: Vec<f64> = (1..=3).map(|k| peak(&cycles, 12 * k - 6)).collect();
    for k in 0..3 {
        // Colder than the end of cool-down (298 K): more mismatch stress; hotter: less.
        assert!(
            cold[k] > residual && hot[k] < residual,
            "{residual:e} {cold:?} {hot:?}"
        );
    }
    // The underfill post-cures in the hot dwells (cure 0.885 → 0.963), so the cold-dwell
    // stress ratchets up, by less each cycle as the cure saturates.
    let growth: Vec<f64> = cold.windows(2).map(|w| w[1] / w[0] - 1.0).collect();
    assert!(
        growth.iter().all(|&g| g > 0.0 && g < 0.02) && growth[1] < growth[0],
        "cold-dwell peaks {cold:?}"
    );
    let (_, before) = cycles.frame("cure", 0).unwrap();
    let (_, after) = cycles
        .frame("cure", cycles.frame_count().unwrap() - 1)
        .unwrap();
    assert!(after.iter().zip(&before).all(|(a, b)| a >= b));
}
