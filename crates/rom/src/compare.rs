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
    })
}
