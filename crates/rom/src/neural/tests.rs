//! Tests of the neural map as a whole: derivatives against finite differences, the fit of
//! snapshots, the model file's round trip, bad input, and a benchmark.

use super::rng::SplitMix;
use super::{NeuralMap, NeuralOptions};
use crate::RomError;
use crate::map::ReducedMap;
use std::path::Path;

/// Grid of n × n points on [0, 1]².
fn grid(n: usize) -> Vec<f64> {
    let h = 1.0 / (n - 1) as f64;
    (0..n * n)
        .flat_map(|i| [(i % n) as f64 * h, (i / n) as f64 * h])
        .collect()
}

/// Smooth 2D snapshots x = X + a u₁(X) + a² u₂(X), one per amplitude.
fn snapshots(reference: &[f64], amplitudes: &[f64]) -> Vec<f64> {
    let pi = std::f64::consts::PI;
    let mut out = Vec::new();
    for &a in amplitudes {
        for x in reference.chunks_exact(2) {
            let u = 0.1 * (pi * x[0]).sin() * (0.5 * pi * x[1]).cos();
            let v = 0.1 * (pi * x[1]).sin() + 0.05 * (pi * x[0] * x[1]).cos();
            out.push(x[0] + a * u + 0.3 * a * a * v);
            out.push(x[1] + a * v - 0.2 * a * u);
        }
    }
    out
}

/// A briefly trained small map of dimension `d`, for derivative and file tests.
fn small_map(d: usize, latent: usize) -> NeuralMap {
    let p = 30;
    let mut rng = SplitMix(7);
    let reference: Vec<f64> = (0..p * d).map(|_| rng.uniform()).collect();
    let s = 4;
    let codes: Vec<f64> = (0..s * latent).map(|_| rng.uniform() - 0.5).collect();
    let snaps: Vec<f64> = (0..s)
        .flat_map(|k| {
            let c = codes[k * latent];
            reference
                .iter()
                .enumerate()
                .map(move |(i, x)| x + 0.1 * c * (3.0 * x + i as f64).sin())
                .collect::<Vec<_>>()
        })
        .collect();
    let options = NeuralOptions {
        width: 16,
        hidden_layers: 2,
        epochs: 5,
        ..Default::default()
    };
    let (map, _) = NeuralMap::train(
        d,
        &reference,
        &snaps,
        latent,
        &codes,
        &options,
        &mut |_, _| {},
    )
    .expect("training");
    map
}

#[test]
fn neural_derivatives_match_finite_differences() {
    for (d, l) in [(2, 3), (3, 2)] {
        let map = small_map(d, l);
        let mut rng = SplitMix(11);
        let n = 12;
        let reference: Vec<f64> = (0..n * d).map(|_| 1.2 * rng.uniform() - 0.1).collect();
        let q: Vec<f64> = (0..l).map(|_| rng.uniform() - 0.5).collect();
        let which = [5u32, 0, 11, 3];
        let mut bound = map.bind(&reference).expect("bind");
        let m = which.len();
        let mut f = vec![0.0; m * d * d];
        let mut jac = vec![0.0; m * d * l];
        bound.gradients(&q, &which, &mut f).expect("gradients");
        bound.jacobians(&q, &which, &mut jac).expect("jacobians");
        let h = 1e-5;
        let (mut plus, mut minus) = (vec![0.0; m * d], vec![0.0; m * d]);
        let mut worst: f64 = 0.0;
        // ∂x/∂q by central differences in q.
        for k in 0..l {
            let mut qp = q.clone();
            qp[k] += h;
            bound.positions(&qp, &which, &mut plus).expect("positions");
            qp[k] -= 2.0 * h;
            bound.positions(&qp, &which, &mut minus).expect("positions");
            for pt in 0..m {
                for i in 0..d {
                    let fd = (plus[pt * d + i] - minus[pt * d + i]) / (2.0 * h);
                    let ad = jac[pt * d * l + i * l + k];
                    worst = worst.max((fd - ad).abs() / ad.abs().max(1e-2));
                }
            }
        }
        // ∂x/∂X by central differences of the reference point.
        for j in 0..d {
            let mut moved = reference.clone();
            let mut back = reference.clone();
            for &i in &which {
                moved[i as usize * d + j] += h;
                back[i as usize * d + j] -= h;
            }
            map.bind(&moved)
                .and_then(|mut b| b.positions(&q, &which, &mut plus))
                .expect("positions");
            map.bind(&back)
                .and_then(|mut b| b.positions(&q, &which, &mut minus))
                .expect("positions");
            for pt in 0..m {
                for i in 0..d {
                    let fd = (plus[pt * d + i] - minus[pt * d + i]) / (2.0 * h);
                    let ad = f[pt * d * d + i * d + j];
                    worst = worst.max((fd - ad).abs() / ad.abs().max(1e-2));
                }
            }
        }
        println!("d = {d}: worst relative derivative error {worst:.2e}");
        assert!(worst < 1e-6, "d = {d}: worst relative error {worst:e}");
        // A different subset after a cached one: fresh results, consistent with the first.
        let mut one = vec![0.0; d * l];
        bound.jacobians(&q, &[11], &mut one).expect("jacobians");
        assert_eq!(one, jac[2 * d * l..3 * d * l]);
    }
}

#[test]
fn neural_fit_reproduces_snapshots() {
    let reference = grid(20);
    let amplitudes: Vec<f64> = (0..10).map(|k| -1.0 + 2.0 * k as f64 / 9.0).collect();
    let snaps = snapshots(&reference, &amplitudes);
    let options = NeuralOptions {
        width: 32,
        hidden_layers: 2,
        epochs: 1500,
        learning_rate: 5e-3,
        batch_points: 200,
        seed: 3,
    };
    let mut epochs = 0;
    let mut last = f64::NAN;
    let start = std::time::Instant::now();
    let (map, codes) = NeuralMap::train(
        2,
        &reference,
        &snaps,
        1,
        &amplitudes,
        &options,
        &mut |e, mse| {
            epochs = e;
            last = mse;
        },
    )
    .expect("training");
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(epochs, options.epochs);
    // Evaluate every snapshot at its trained code.
    let p = reference.len() / 2;
    let which: Vec<u32> = (0..p as u32).collect();
    let mut bound = map.bind(&reference).expect("bind");
    let mut x = vec![0.0; p * 2];
    let (mut err, mut disp) = (0.0, 0.0);
    for (s, code) in codes.iter().enumerate() {
        bound
            .positions(&[*code], &which, &mut x)
            .expect("positions");
        let snap = &snaps[s * p * 2..(s + 1) * p * 2];
        for ((a, b), r) in x.iter().zip(snap).zip(&reference) {
            err += (a - b).powi(2);
            disp += (b - r).powi(2);
        }
    }
    let relative = (err / disp).sqrt();
    println!("fit: {seconds:.2} s, last epoch mse {last:.3e} m², relative RMS error {relative:.4}");
    // Tolerance: RMS position error below 5% of the RMS displacement.
    assert!(relative < 0.05, "relative RMS error {relative}");
}

#[test]
fn neural_round_trip_and_bad_models() {
    let map = small_map(2, 2);
    let (info, arrays) = map.to_arrays();
    // Training is deterministic for a given seed.
    assert_eq!(small_map(2, 2).to_arrays(), (info.clone(), arrays.clone()));
    let path = Path::new("model.safetensors");
    let back = NeuralMap::from_arrays(path, &info, arrays.clone()).expect("from_arrays");
    let reference = grid(5);
    let which: Vec<u32> = (0..25).collect();
    let (mut a, mut b) = (vec![0.0; 50], vec![0.0; 50]);
    let q = [0.3, -0.2];
    map.bind(&reference)
        .and_then(|mut m| m.positions(&q, &which, &mut a))
        .expect("positions");
    back.bind(&reference)
        .and_then(|mut m| m.positions(&q, &which, &mut b))
        .expect("positions");
    assert_eq!(a, b);
    let is_bad = |r: Result<NeuralMap, RomError>| matches!(r, Err(RomError::BadModel { .. }));
    let mut missing = arrays.clone();
    missing.remove(1);
    assert!(is_bad(NeuralMap::from_arrays(path, &info, missing)));
    let mut wrong = arrays.clone();
    wrong[0].shape.reverse();
    assert!(is_bad(NeuralMap::from_arrays(path, &info, wrong)));
    let mut info_bad = info.clone();
    info_bad["activation"] = "relu".into();
    assert!(is_bad(NeuralMap::from_arrays(
        path,
        &info_bad,
        arrays.clone()
    )));
    let mut info_bad = info.clone();
    info_bad["latent_std"] = serde_json::json!([1.0]);
    assert!(is_bad(NeuralMap::from_arrays(path, &info_bad, arrays)));
}

#[test]
fn neural_bad_input_is_an_error() {
    let reference = grid(3);
    let codes = [0.0, 1.0];
    let snaps = snapshots(&reference, &codes);
    let options = NeuralOptions {
        epochs: 1,
        width: 4,
        ..Default::default()
    };
    let train = |r: &[f64], s: &[f64], l: usize, c: &[f64]| {
        NeuralMap::train(2, r, s, l, c, &options, &mut |_, _| {})
    };
    assert!(train(&reference, &snaps[1..], 1, &codes).is_err());
    assert!(train(&reference[1..], &snaps, 1, &codes).is_err());
    assert!(train(&reference, &snaps, 2, &codes[..1]).is_err());
    assert!(train(&reference, &snaps, 0, &codes).is_err());
    let mut nan = snaps.clone();
    nan[7] = f64::NAN;
    assert!(matches!(
        train(&reference, &nan, 1, &codes),
        Err(RomError::Training(_))
    ));
    let (map, _) = train(&reference, &snaps, 1, &codes).expect("training");
    assert!(map.bind(&reference[1..]).is_err());
    let mut bound = map.bind(&reference).expect("bind");
    let mut out = vec![0.0; 4];
    assert!(bound.positions(&[0.0, 1.0], &[0, 1], &mut out).is_err());
    assert!(bound.positions(&[0.0], &[0, 9], &mut out).is_err());
    assert!(bound.positions(&[0.0], &[0], &mut out).is_err());
    assert!(bound.gradients(&[0.0], &[0, 1], &mut out[..3]).is_err());
    assert!(bound.jacobians(&[0.0], &[0, 1], &mut out[..3]).is_err());
    assert!(bound.positions(&[0.0], &[], &mut []).is_ok());
    assert!(bound.gradients(&[0.0], &[], &mut []).is_ok());
}

/// Timing at the intended scale: `cargo test --release neural_benchmark -- --ignored --nocapture`.
#[test]
#[ignore]
fn neural_benchmark() {
    let (s, p, latent) = (200, 2000, 8);
    let mut rng = SplitMix(1);
    let reference: Vec<f64> = (0..p * 2).map(|_| rng.uniform()).collect();
    let codes: Vec<f64> = (0..s * latent).map(|_| rng.uniform() - 0.5).collect();
    let mut snaps = Vec::with_capacity(s * p * 2);
    for c in codes.chunks_exact(latent) {
        for x in reference.chunks_exact(2) {
            let a: f64 = c
                .iter()
                .enumerate()
                .map(|(k, v)| v * (k as f64 * x[0]).sin())
                .sum();
            snaps.push(x[0] + 0.05 * a);
            snaps.push(x[1] + 0.05 * a * x[1]);
        }
    }
    let epochs = std::env::var("NEURAL_BENCH_EPOCHS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300);
    let options = NeuralOptions {
        epochs,
        ..Default::default()
    };
    let start = std::time::Instant::now();
    let mut last = 0.0;
    NeuralMap::train(
        2,
        &reference,
        &snaps,
        latent,
        &codes,
        &options,
        &mut |e, mse| {
            last = mse;
            if e % 50 == 0 {
                println!(
                    "epoch {e}: mse {mse:.3e}, {:.1} s",
                    start.elapsed().as_secs_f64()
                );
            }
        },
    )
    .expect("training");
    println!("{} s, final mse {last:.3e}", start.elapsed().as_secs_f64());
}
