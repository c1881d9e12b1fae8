//! The error of a run against a reference run of the same scene (a reduced run against the
//! full-order run, say): relative L2 position error over all particles and frames.

use crate::RomError;
use mpm_io::ResultStore;
use serde::Serialize;
use std::path::Path;

/// Position error of one run against another.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PositionError {
    /// sqrt(Σ_frames Σ_particles |x − x_ref|²) / sqrt(Σ_frames Σ_particles |x_ref|²), the
    /// paper's measure (positions as stored, so it depends on where the origin is).
    pub relative: f64,
    /// The same misfit relative to the reference's displacement from its first frame,
    /// sqrt(Σ |x − x_ref|²) / sqrt(Σ |x_ref − X|²): independent of the origin, and stricter.
    pub relative_to_displacement: f64,
    /// Largest distance of one particle from its reference position in any frame, metres.
    pub max_distance: f64,
    /// Frames compared.
    pub frames: usize,
    /// Particles compared.
    pub particles: usize,
    /// Σ |x − x_ref|², m² (the sums behind both measures, so runs can be summed).
    pub misfit_squared: f64,
    /// Σ |x_ref|², m².
    pub position_squared: f64,
    /// Σ |x_ref − X|², m².
    pub displacement_squared: f64,
}

impl PositionError {
    /// Both measures over several runs together (each sum over every run's frames and
    /// particles, as the paper sums its errors over the held-out parameters); the largest
    /// distance of any; frames and particles added up.
    pub fn summed(errors: &[PositionError]) -> PositionError {
        let sum = |f: fn(&PositionError) -> f64| errors.iter().map(f).sum::<f64>();
        let (misfit, position, displacement) = (
            sum(|e| e.misfit_squared),
            sum(|e| e.position_squared),
            sum(|e| e.displacement_squared),
        );
        PositionError {
            relative: (misfit / position.max(1e-300)).sqrt(),
            relative_to_displacement: (misfit / displacement.max(1e-300)).sqrt(),
            max_distance: errors.iter().map(|e| e.max_distance).fold(0.0, f64::max),
            frames: errors.iter().map(|e| e.frames).sum(),
            particles: errors.iter().map(|e| e.particles).sum(),
            misfit_squared: misfit,
            position_squared: position,
            displacement_squared: displacement,
        }
    }
}

fn mismatch(message: String) -> RomError {
    RomError::Mismatch {
        path: "stores".into(),
        message,
    }
}

/// Compares the `x` frames of the store `run` with those of `reference`. Both must hold
/// the same particles (in the same order) at the same output times.
pub fn position_error(run: &Path, reference: &Path) -> Result<PositionError, RomError> {
    let a = ResultStore::open(run)?;
    let b = ResultStore::open(reference)?;
    if a.dimension() != b.dimension() {
        return Err(mismatch(format!(
            "{} is {}D but {} is {}D",
            run.display(),
            a.dimension(),
            reference.display(),
            b.dimension()
        )));
    }
    let (ta, tb) = (a.times()?, b.times()?);
    if ta.len() != tb.len() {
        return Err(mismatch(format!(
            "{} has {} frames but {} has {}; compare runs with the same output.frames and \
             end time",
            run.display(),
            ta.len(),
            reference.display(),
            tb.len()
        )));
    }
    let end = tb.last().copied().unwrap_or(0.0).abs().max(1e-300);
    if let Some(k) = ta
        .iter()
        .zip(&tb)
        .position(|(x, y)| (x - y).abs() > 1e-6 * end)
    {
        return Err(mismatch(format!(
            "frame {k} is at t = {} s in {} but t = {} s in {}",
            ta[k],
            run.display(),
            tb[k],
            reference.display()
        )));
    }
    let (_, first) = b.frame("x", 0)?;
    let (mut err2, mut pos2, mut disp2, mut max_distance) = (0.0, 0.0, 0.0, 0.0f64);
    let dim = a.dimension();
    for k in 0..ta.len() as u64 {
        let (_, xa) = a.frame("x", k)?;
        let (_, xb) = b.frame("x", k)?;
        if xa.len() != xb.len() {
            return Err(mismatch(format!(
                "{} has {} particles but {} has {}; a super-resolved run must be compared \
                 with a full-order run at the same resolution",
                run.display(),
                xa.len() / dim,
                reference.display(),
                xb.len() / dim
            )));
        }
        for ((pa, pb), p0) in xa
            .chunks_exact(dim)
            .zip(xb.chunks_exact(dim))
            .zip(first.chunks_exact(dim))
        {
            let mut e2 = 0.0;
            for d in 0..dim {
                let e = pa[d] - pb[d];
                e2 += e * e;
                pos2 += pb[d] * pb[d];
                let u = pb[d] - p0[d];
                disp2 += u * u;
            }
            err2 += e2;
            max_distance = max_distance.max(e2.sqrt());
        }
    }
    Ok(PositionError {
        relative: (err2 / pos2.max(1e-300)).sqrt(),
        relative_to_displacement: (err2 / disp2.max(1e-300)).sqrt(),
        max_distance,
        frames: ta.len(),
        particles: first.len() / dim,
        misfit_squared: err2,
        position_squared: pos2,
        displacement_squared: disp2,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(misfit: f64, position: f64, displacement: f64) -> PositionError {
        PositionError {
            relative: (misfit / position).sqrt(),
            relative_to_displacement: (misfit / displacement).sqrt(),
            max_distance: misfit.sqrt(),
            frames: 3,
            particles: 10,
            misfit_squared: misfit,
            position_squared: position,
            displacement_squared: displacement,
        }
    }

    #[test]
    fn summed_errors_weigh_each_run_by_its_sums() {
        let total = PositionError::summed(&[error(1.0, 100.0, 4.0), error(3.0, 300.0, 12.0)]);
        assert!((total.relative - 0.1).abs() < 1e-15);
        assert!((total.relative_to_displacement - 0.5).abs() < 1e-15);
        assert_eq!(total.max_distance, 3.0f64.sqrt());
        assert_eq!((total.frames, total.particles), (6, 20));
        let one = error(1.0, 100.0, 4.0);
        assert_eq!(PositionError::summed(&[one]).relative, one.relative);
    }
}
