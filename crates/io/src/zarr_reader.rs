//! Reads result stores back: metadata, frames of particle fields, and particles to start a
//! new body from.

use crate::IoError;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::Array;
use zarrs::filesystem::FilesystemStore;
use zarrs::group::Group;

/// A stored table: its column names and its rows (one number per column each).
pub type TableData = (Vec<String>, Vec<Vec<f64>>);

/// An open result store.
pub struct ResultStore {
    path: PathBuf,
    store: Arc<FilesystemStore>,
    attributes: serde_json::Map<String, serde_json::Value>,
    /// Group of the stage read (`/stages/<i>-<name>`), or empty for the root.
    prefix: String,
    /// The metrics of the stage read (its group's `metrics` attribute), if one was chosen.
    stage_metrics: Option<serde_json::Value>,
}

fn zerr(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Zarr {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

impl ResultStore {
    /// Opens a store written by `mpm run`.
    pub fn open(path: impl Into<PathBuf>) -> Result<Self, IoError> {
        let path = path.into();
        if !path.join("zarr.json").is_file() {
            return Err(IoError::Layout {
                path: path.display().to_string(),
                message: "not a Zarr v3 store (no zarr.json)".into(),
            });
        }
        let store = Arc::new(FilesystemStore::new(&path).map_err(|e| zerr(&path, e))?);
        let root = Group::open(store.clone(), "/").map_err(|e| zerr(&path, e))?;
        let attributes = root.attributes().clone();
        if !attributes.contains_key("mpm_version") {
            return Err(IoError::Layout {
                path: path.display().to_string(),
                message: "not a store written by mpm (no mpm_version attribute)".into(),
            });
        }
        Ok(Self {
            path,
            store,
            attributes,
            prefix: String::new(),
            stage_metrics: None,
        })
    }

    /// The stages of a staged run's store (`<index>-<name>`, in order); empty otherwise.
    pub fn stages(&self) -> Vec<String> {
        let mut stages: Vec<(usize, String)> = std::fs::read_dir(self.path.join("stages"))
            .into_iter()
            .flatten()
            .filter_map(Result::ok)
            .filter(|e| e.path().join("zarr.json").is_file())
            .filter_map(|e| e.file_name().into_string().ok())
            .filter_map(|name| {
                let index = name.split('-').next()?.parse().ok()?;
                Some((index, name))
            })
            .collect();
        stages.sort();
        stages.into_iter().map(|(_, name)| name).collect()
    }

    /// Reads the stage `name` (its name, or `<index>-<name>`) of a staged run's store; the
    /// root's frames otherwise are not there.
    pub fn stage(mut self, name: &str) -> Result<Self, IoError> {
        let stages = self.stages();
        let found = stages
            .iter()
            .find(|s| s.as_str() == name || s.split_once('-').map(|(_, n)| n) == Some(name))
            .ok_or_else(|| IoError::Layout {
                path: self.path.display().to_string(),
                message: if stages.is_empty() {
                    format!("no stage `{name}`: the store is not a staged run's")
                } else {
                    format!("no stage `{name}` (stages: {})", stages.join(", "))
                },
            })?;
        self.prefix = format!("/stages/{found}");
        let group =
            Group::open(self.store.clone(), &self.prefix).map_err(|e| zerr(&self.path, e))?;
        self.stage_metrics = group.attributes().get("metrics").cloned();
        Ok(self)
    }

    /// The metrics of what is read: the chosen stage's (its figures and tables), else the
    /// run's.
    pub fn metrics(&self) -> Option<&serde_json::Value> {
        self.stage_metrics
            .as_ref()
            .or_else(|| self.attributes.get("metrics"))
    }

    /// Opens a store and, for a staged run's store, the stage `name` (default: the last).
    pub fn open_stage(path: impl Into<PathBuf>, name: Option<&str>) -> Result<Self, IoError> {
        let store = Self::open(path)?;
        match (name, store.stages().last().cloned()) {
            (Some(name), _) => store.stage(name),
            (None, Some(last)) => store.stage(&last),
            (None, None) => Ok(store),
        }
    }

    /// The stage read (`<index>-<name>`), if any.
    pub fn stage_name(&self) -> Option<&str> {
        self.prefix.strip_prefix("/stages/")
    }

    /// The folder of the stage read (or of the store).
    fn dir(&self) -> PathBuf {
        self.path.join(self.prefix.trim_start_matches('/'))
    }

    /// Root attributes (`scene`, `metrics`, ...).
    pub fn attributes(&self) -> &serde_json::Map<String, serde_json::Value> {
        &self.attributes
    }

    /// Spatial dimension of the run.
    pub fn dimension(&self) -> usize {
        self.attributes
            .get("dimension")
            .and_then(|d| d.as_u64())
            .unwrap_or(3) as usize
    }

    /// Output times.
    pub fn times(&self) -> Result<Vec<f64>, IoError> {
        let array = Array::open(self.store.clone(), &format!("{}/time", self.prefix))
            .map_err(|e| zerr(&self.path, e))?;
        array
            .retrieve_array_subset::<Vec<f64>>(&array.subset_all())
            .map_err(|e| zerr(&self.path, e))
    }

    /// A per-frame diagnostic (`kinetic_energy`, `strain_energy`, `total_energy`, ...).
    pub fn diagnostic(&self, name: &str) -> Result<Vec<f64>, IoError> {
        let array = Array::open(
            self.store.clone(),
            &format!("{}/diagnostics/{name}", self.prefix),
        )
        .map_err(|e| zerr(&self.path, e))?;
        array
            .retrieve_array_subset::<Vec<f64>>(&array.subset_all())
            .map_err(|e| zerr(&self.path, e))
    }

    /// Names of the stored particle fields.
    pub fn fields(&self) -> Result<Vec<String>, IoError> {
        let dir = self.dir().join("particles");
        let entries = std::fs::read_dir(&dir).map_err(|source| IoError::File {
            path: dir.display().to_string(),
            source,
        })?;
        let mut names: Vec<String> = entries
            .filter_map(|e| e.ok())
            .filter(|e| e.path().join("zarr.json").is_file())
            .filter_map(|e| e.file_name().into_string().ok())
            .collect();
        names.sort();
        Ok(names)
    }

    /// Particles of a field as its metadata states them (read before any frame is).
    pub fn particle_count(&self, field: &str) -> Result<u64, IoError> {
        let array = Array::open(
            self.store.clone(),
            &format!("{}/particles/{field}", self.prefix),
        )
        .map_err(|e| zerr(&self.path, e))?;
        let shape = array.shape();
        if shape.len() < 2 || shape[2..].iter().any(|&c| c > 3) {
            return Err(IoError::Layout {
                path: self.path.display().to_string(),
                message: format!("field `{field}` has the shape {shape:?}"),
            });
        }
        Ok(shape[1])
    }

    /// One frame of a field: its per-particle shape and values (particle-major).
    pub fn frame(&self, field: &str, frame: u64) -> Result<(Vec<u64>, Vec<f64>), IoError> {
        let array = Array::open(
            self.store.clone(),
            &format!("{}/particles/{field}", self.prefix),
        )
        .map_err(|e| zerr(&self.path, e))?;
        let shape = array.shape().to_vec();
        if frame >= shape[0] {
            return Err(IoError::Layout {
                path: self.path.display().to_string(),
                message: format!("field `{field}` has {} frames, not {}", shape[0], frame + 1),
            });
        }
        let mut chunk = vec![0u64; shape.len()];
        chunk[0] = frame;
        let values = array
            .retrieve_chunk::<Vec<f64>>(&chunk)
            .map_err(|e| zerr(&self.path, e))?;
        Ok((shape[1..].to_vec(), values))
    }

    /// A table the physics operators kept (`tables/<name>`): its column names and rows;
    /// `None` when the store has no such table.
    pub fn table(&self, name: &str) -> Result<Option<TableData>, IoError> {
        if !crate::zarr_writer::valid_table_name(name) {
            return Ok(None);
        }
        if !self
            .dir()
            .join("tables")
            .join(name)
            .join("zarr.json")
            .is_file()
        {
            return Ok(None);
        }
        let layout = |message: String| IoError::Layout {
            path: self.path.display().to_string(),
            message,
        };
        let array = Array::open(
            self.store.clone(),
            &format!("{}/tables/{name}", self.prefix),
        )
        .map_err(|e| zerr(&self.path, e))?;
        let columns: Vec<String> = array
            .attributes()
            .get("columns")
            .and_then(|c| c.as_array())
            .and_then(|c| c.iter().map(|n| n.as_str().map(String::from)).collect())
            .ok_or_else(|| layout(format!("table `{name}` has no `columns` attribute")))?;
        let &[rows, width] = array.shape() else {
            return Err(layout(format!("table `{name}` is not two-dimensional")));
        };
        if width != columns.len() as u64 {
            return Err(layout(format!(
                "table `{name}` has {width} columns but names {}",
                columns.len()
            )));
        }
        if rows == 0 || width == 0 {
            return Ok(Some((columns, vec![Vec::new(); rows as usize])));
        }
        let values = array
            .retrieve_array_subset::<Vec<f64>>(&array.subset_all())
            .map_err(|e| zerr(&self.path, e))?;
        let rows = values
            .chunks_exact(width as usize)
            .map(<[f64]>::to_vec)
            .collect();
        Ok(Some((columns, rows)))
    }

    /// Number of frames stored.
    pub fn frame_count(&self) -> Result<u64, IoError> {
        Ok(self.times()?.len() as u64)
    }
}

/// Reads the last frame's positions (and volumes when stored) of a result store, to start a
/// body from it; `spacing^dim` is the volume when the store has none.
pub fn read_particles(
    path: &Path,
    dim: usize,
    spacing: f64,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let store = ResultStore::open(path).map_err(|e| e.to_string())?;
    if store.dimension() != dim {
        return Err(format!(
            "`{}` holds a {}D run; this scene is {dim}D",
            path.display(),
            store.dimension()
        ));
    }
    let frames = store.frame_count().map_err(|e| e.to_string())?;
    if frames == 0 {
        return Err(format!("`{}` has no frames", path.display()));
    }
    // The store's own metadata says how much a frame holds: check it before reading one.
    let count = store.particle_count("x").map_err(|e| e.to_string())?;
    let limit = mpm_core::scene::Limits::current().max_particles;
    if count > limit {
        return Err(format!(
            "`{}` holds {count} particles; at most {limit} are allowed (limit `particles`)",
            path.display()
        ));
    }
    let (_, positions) = store.frame("x", frames - 1).map_err(|e| e.to_string())?;
    let n = positions.len() / dim;
    let volumes = match store.frame("volume", frames - 1) {
        Ok((_, v)) => v,
        Err(_) => vec![spacing.powi(dim as i32); n],
    };
    Ok((positions, volumes))
}
