//! Proper orthogonal decomposition of displacement snapshots by the method of snapshots:
//! the modes are the leading eigenvectors of the snapshot Gram matrix, so the cost grows with
//! the number of snapshots, not of particles.

use crate::RomError;
use crate::snapshots::Snapshots;
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// The leading POD modes of a set of snapshots.
#[derive(Clone, Debug)]
pub struct Pod {
    /// Modes, `[mode][particle][axis]`, scaled to unit RMS over the particles, so the
    /// coefficient of a mode is the RMS displacement (metres) it carries.
    pub modes: Vec<f64>,
    /// Number of modes kept.
    pub count: usize,
    /// Singular value of every mode found (all of them, not only the kept ones).
    pub singular_values: Vec<f64>,
    /// Share of the snapshots' squared displacement the kept modes capture.
    pub captured: f64,
    /// Coefficients of each snapshot on the kept modes, `[snapshot][mode]`.
    pub coefficients: Vec<f64>,
}

/// Computes `count` POD modes of the snapshots' displacements.
pub fn pod(snapshots: &Snapshots, count: usize) -> Result<Pod, RomError> {
    let s_count = snapshots.count();
    let n = snapshots.reference.len();
    let particles = snapshots.particles();
    if count == 0 {
        return Err(RomError::Option("--latent must be at least 1".into()));
    }
    // Displacements, one row per snapshot.
    let mut u = vec![0.0; s_count * n];
    u.par_chunks_mut(n)
        .enumerate()
        .for_each(|(s, row)| snapshots.displacement(s, row));
    // Gram matrix G[a][b] = u_a · u_b.
    let pairs: Vec<(usize, usize)> = (0..s_count)
        .flat_map(|a| (a..s_count).map(move |b| (a, b)))
        .collect();
    let dots: Vec<f64> = pairs
        .par_iter()
        .map(|&(a, b)| {
            u[a * n..(a + 1) * n]
                .iter()
                .zip(&u[b * n..(b + 1) * n])
                .map(|(x, y)| x * y)
                .sum()
        })
        .collect();
    let mut gram = DMatrix::<f64>::zeros(s_count, s_count);
    for (&(a, b), &d) in pairs.iter().zip(&dots) {
        gram[(a, b)] = d;
        gram[(b, a)] = d;
    }
    let total: f64 = (0..s_count).map(|a| gram[(a, a)]).sum();
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        return Err(RomError::Training(
            "the training runs do not move: every displacement is zero".into(),
        ));
    }
    let eigen = SymmetricEigen::new(gram);
    let mut order: Vec<usize> = (0..s_count).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let singular_values: Vec<f64> = order
        .iter()
        .map(|&k| eigen.eigenvalues[k].max(0.0).sqrt())
        .collect();
    // Modes whose singular value is round-off carry no information.
    let usable = singular_values
        .iter()
        .take_while(|&&s| s > 1e-7 * singular_values[0])
        .count();
    if count > usable {
        return Err(RomError::Training(format!(
            "--latent {count} asks for more modes than the snapshots hold ({usable} independent \
             displacement fields in {s_count} snapshots); add training runs or lower --latent"
        )));
    }
    let scale = (particles as f64).sqrt();
    let mut modes = vec![0.0; count * n];
    modes.par_chunks_mut(n).enumerate().for_each(|(k, mode)| {
        let column = order[k];
        let factor = scale / singular_values[k];
        for s in 0..s_count {
            let c = eigen.eigenvectors[(s, column)] * factor;
            for (m, v) in mode.iter_mut().zip(&u[s * n..(s + 1) * n]) {
                *m += c * v;
            }
        }
    });
    let captured = singular_values[..count].iter().map(|s| s * s).sum::<f64>() / total;
    let mut coefficients = vec![0.0; s_count * count];
    coefficients
        .par_chunks_mut(count)
        .enumerate()
        .for_each(|(s, c)| {
            for (k, ck) in c.iter_mut().enumerate() {
                let dot: f64 = modes[k * n..(k + 1) * n]
                    .iter()
                    .zip(&u[s * n..(s + 1) * n])
                    .map(|(a, b)| a * b)
                    .sum();
                *ck = dot / particles as f64;
            }
        });
    Ok(Pod {
        modes,
        count,
        singular_values,
        captured,
        coefficients,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pod_recovers_a_two_mode_family_and_refuses_too_many_modes() {
        // Snapshots u = a·f + b·g of two fixed fields: two modes capture everything.
        let n = 50;
        let reference: Vec<f64> = (0..n).flat_map(|p| [p as f64, 0.0]).collect();
        let mut positions = Vec::new();
        for (a, b) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.5, -0.3), (2.0, 1.0)] {
            for p in 0..n {
                let x = p as f64 / n as f64;
                positions.push(reference[2 * p] + a * x * x);
                positions.push(b * (3.0 * x).sin());
            }
        }
        let s = Snapshots {
            dimension: 2,
            reference,
            positions,
            runs: Vec::new(),
            scene: serde_json::Value::Null,
        };
        let pod = pod(&s, 2).unwrap();
        assert!(pod.captured > 1.0 - 1e-12, "{}", pod.captured);
        // Reconstruction of snapshot 3 from its coefficients.
        let mut u = vec![0.0; 2 * n];
        s.displacement(3, &mut u);
        for (i, ui) in u.iter().enumerate() {
            let r: f64 = (0..2)
                .map(|k| pod.coefficients[3 * 2 + k] * pod.modes[k * 2 * n + i])
                .sum();
            assert!((r - ui).abs() < 1e-10);
        }
        assert!(matches!(crate::pod::pod(&s, 3), Err(RomError::Training(_))));
    }
}
