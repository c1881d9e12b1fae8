//! Training data: the position frames of full-order result stores, all of the same particles,
//! as displacement snapshots from the first frame.

use crate::RomError;
use mpm_io::ResultStore;
use std::path::{Path, PathBuf};

/// One training run as read.
#[derive(Clone, Debug)]
pub struct TrainingRun {
    /// Store path.
    pub path: PathBuf,
    /// Output times of its frames.
    pub times: Vec<f64>,
}

/// The position frames of every training run, one snapshot per frame.
#[derive(Clone, Debug)]
pub struct Snapshots {
    /// 2 or 3.
    pub dimension: usize,
    /// Reference positions (the first frame), `dimension` numbers per particle.
    pub reference: Vec<f64>,
    /// Positions of every snapshot, `[snapshot][particle][axis]`.
    pub positions: Vec<f64>,
    /// The runs, in the order their snapshots appear.
    pub runs: Vec<TrainingRun>,
    /// The first run's scene (defaults filled in), as stored with its results.
    pub scene: serde_json::Value,
}

impl Snapshots {
    /// Number of particles.
    pub fn particles(&self) -> usize {
        self.reference.len() / self.dimension
    }

    /// Number of snapshots.
    pub fn count(&self) -> usize {
        self.positions.len() / self.reference.len().max(1)
    }

    /// Displacement of snapshot `s` from the reference, `dimension` numbers per particle.
    pub fn displacement(&self, s: usize, out: &mut [f64]) {
        let n = self.reference.len();
        for ((o, x), x0) in out
            .iter_mut()
            .zip(&self.positions[s * n..(s + 1) * n])
            .zip(&self.reference)
        {
            *o = x - x0;
        }
    }
}

/// The result stores named by `paths`: a path holding `zarr.json` is a store; any other
/// folder contributes every `*.zarr` store directly inside it, in name order.
pub fn find_stores(paths: &[PathBuf]) -> Result<Vec<PathBuf>, RomError> {
    let mut stores = Vec::new();
    for path in paths {
        if path.join("zarr.json").is_file() {
            stores.push(path.clone());
            continue;
        }
        let entries = std::fs::read_dir(path).map_err(|e| RomError::File {
            path: path.display().to_string(),
            message: format!("not a result store nor a folder of stores ({e})"),
        })?;
        let mut found: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "zarr") && p.join("zarr.json").is_file())
            .collect();
        found.sort();
        if found.is_empty() {
            return Err(RomError::Training(format!(
                "{} holds no result store (*.zarr)",
                path.display()
            )));
        }
        stores.extend(found);
    }
    if stores.is_empty() {
        return Err(RomError::Training("no training runs given".into()));
    }
    Ok(stores)
}

/// Reads the `x` frames of every store. All runs must be of the same dimension and start
/// from the same particles (the same scene at different parameters).
pub fn load(stores: &[PathBuf]) -> Result<Snapshots, RomError> {
    let mut result: Option<Snapshots> = None;
    for path in stores {
        let store = ResultStore::open(path)?;
        let dim = store.dimension();
        if !store.fields()?.iter().any(|f| f == "x") {
            return Err(RomError::Training(format!(
                "{} has no `x` (position) field; add \"x\" to output.fields of the training scene",
                path.display()
            )));
        }
        let times = store.times()?;
        if times.len() < 2 {
            return Err(RomError::Training(format!(
                "{} has {} frame(s); a training run needs at least 2",
                path.display(),
                times.len()
            )));
        }
        let (_, first) = store.frame("x", 0)?;
        match &mut result {
            None => {
                result = Some(Snapshots {
                    dimension: dim,
                    reference: first.clone(),
                    positions: Vec::new(),
                    runs: Vec::new(),
                    scene: store
                        .attributes()
                        .get("scene")
                        .cloned()
                        .unwrap_or(serde_json::Value::Null),
                });
            }
            Some(s) => check_same_particles(s, path, dim, &first)?,
        }
        let s = result.as_mut().expect("set above");
        for k in 0..times.len() as u64 {
            let (_, x) = store.frame("x", k)?;
            if x.len() != s.reference.len() {
                return Err(RomError::Training(format!(
                    "{}: frame {k} has {} numbers, the first frame {}",
                    path.display(),
                    x.len(),
                    s.reference.len()
                )));
            }
            if let Some(bad) = x.iter().position(|v| !v.is_finite()) {
                return Err(RomError::Training(format!(
                    "{}: frame {k} has a non-finite position (particle {}); the run blew up",
                    path.display(),
                    bad / dim
                )));
            }
            s.positions.extend_from_slice(&x);
        }
        s.runs.push(TrainingRun {
            path: path.clone(),
            times,
        });
    }
    result.ok_or_else(|| RomError::Training("no training runs given".into()))
}

fn check_same_particles(
    s: &Snapshots,
    path: &Path,
    dim: usize,
    first: &[f64],
) -> Result<(), RomError> {
    let base = &s.runs[0].path;
    if dim != s.dimension {
        return Err(RomError::Training(format!(
            "{} is {dim}D but {} is {}D",
            path.display(),
            base.display(),
            s.dimension
        )));
    }
    if first.len() != s.reference.len() {
        return Err(RomError::Training(format!(
            "{} has {} particles but {} has {}; every run must use the same particles",
            path.display(),
            first.len() / dim,
            base.display(),
            s.reference.len() / dim
        )));
    }
    let extent = s
        .reference
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-300);
    if let Some(p) = first
        .iter()
        .zip(&s.reference)
        .position(|(a, b)| (a - b).abs() > 1e-9 * extent)
    {
        return Err(RomError::Training(format!(
            "{} starts from other particle positions than {} (particle {} differs); train on \
             runs of one scene at different parameters",
            path.display(),
            base.display(),
            p / dim
        )));
    }
    Ok(())
}
