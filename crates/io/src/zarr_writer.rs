//! Writes a run into a Zarr v3 store, frame by frame, so a stopped or killed run keeps every
//! frame written before it.

use crate::IoError;
use mpm_core::output::{
    FRAME_DIAGNOSTICS, Frame, Metrics, OutputError, OutputSink, RunInfo, StageInfo,
};
use mpm_core::physics::Table;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::codec::ZstdCodec;
use zarrs::array::{Array, ArrayBuilder, ArraySubset, data_type};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::{Group, GroupBuilder};

/// Frames per chunk of the 1D per-frame arrays (`time`, `diagnostics/*`).
const SCALAR_CHUNK: u64 = 256;

/// An [`OutputSink`] writing a Zarr v3 store.
pub struct ZarrSink {
    path: PathBuf,
    store: Option<Arc<FilesystemStore>>,
    root: Option<Group<FilesystemStore>>,
    time: Option<Array<FilesystemStore>>,
    diagnostics: Vec<Array<FilesystemStore>>,
    fields: Vec<(Array<FilesystemStore>, Vec<u64>)>,
    frames: u64,
    /// Continue an existing store after this many frames instead of creating one.
    resume_after: Option<u64>,
    /// In a staged run: the group of the stage being written (`/stages/<i>-<name>`), and
    /// the whole staged scene for the root attributes.
    stage: Option<(String, serde_json::Value)>,
}

fn zerr(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Zarr {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

fn out(e: IoError) -> OutputError {
    OutputError(e.to_string())
}

impl ZarrSink {
    /// A sink that will create the store at `path` (an existing store there is replaced).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            store: None,
            root: None,
            time: None,
            diagnostics: Vec::new(),
            fields: Vec::new(),
            frames: 0,
            resume_after: None,
            stage: None,
        }
    }

    /// A sink that continues the store at `path` after its first `frames` frames (those a
    /// checkpoint was written after; frames written later by the interrupted run are
    /// overwritten).
    pub fn resume(path: impl Into<PathBuf>, frames: usize) -> Self {
        Self {
            resume_after: Some(frames as u64),
            ..Self::new(path)
        }
    }

    /// Where the per-frame arrays go: the root, or the stage's group.
    fn prefix(&self) -> &str {
        self.stage.as_ref().map_or("", |(group, _)| group.as_str())
    }

    /// Opens the existing store and cuts its per-frame arrays to `frames` frames.
    fn reopen(&mut self, info: &RunInfo<'_>, frames: u64) -> Result<(), IoError> {
        let path = self.path.clone();
        let store = Arc::new(FilesystemStore::new(&path).map_err(|e| zerr(&path, e))?);
        let prefix = self.prefix().to_string();
        let mut root = Group::open(store.clone(), "/").map_err(|e| zerr(&path, e))?;
        root.attributes_mut()
            .insert("metrics".into(), serde_json::Value::Null);
        root.store_metadata().map_err(|e| zerr(&path, e))?;
        if !prefix.is_empty() {
            let mut group = Group::open(store.clone(), &prefix).map_err(|e| zerr(&path, e))?;
            group
                .attributes_mut()
                .insert("metrics".into(), serde_json::Value::Null);
            group.store_metadata().map_err(|e| zerr(&path, e))?;
        }
        let open = |name: &str| -> Result<Array<FilesystemStore>, IoError> {
            let array = Array::open(store.clone(), name).map_err(|e| zerr(&path, e))?;
            if array.shape().first().copied().unwrap_or(0) < frames {
                return Err(IoError::Layout {
                    path: path.display().to_string(),
                    message: format!("{name} has fewer than the checkpoint's {frames} frames"),
                });
            }
            Ok(array)
        };
        let mut time = open(&format!("{prefix}/time"))?;
        time.set_shape(vec![frames]).map_err(|e| zerr(&path, e))?;
        time.store_metadata().map_err(|e| zerr(&path, e))?;
        self.diagnostics = Vec::new();
        for name in FRAME_DIAGNOSTICS {
            let mut array = open(&format!("{prefix}/diagnostics/{name}"))?;
            array.set_shape(vec![frames]).map_err(|e| zerr(&path, e))?;
            array.store_metadata().map_err(|e| zerr(&path, e))?;
            self.diagnostics.push(array);
        }
        self.fields = Vec::new();
        for field in info.fields {
            let mut array = open(&format!("{prefix}/particles/{}", field.name))?;
            let mut shape = array.shape().to_vec();
            shape[0] = frames;
            array.set_shape(shape.clone()).map_err(|e| zerr(&path, e))?;
            array.store_metadata().map_err(|e| zerr(&path, e))?;
            self.fields.push((array, shape));
        }
        self.time = Some(time);
        self.frames = frames;
        self.root = Some(root);
        self.store = Some(store);
        Ok(())
    }

    /// Where the store is.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn create(&mut self, info: &RunInfo<'_>) -> Result<(), IoError> {
        zarrs::config::global_config_mut().set_include_zarrs_metadata(false);
        let path = self.path.clone();
        let prefix = self.prefix().to_string();
        if let (Some(store), Some((group, _))) = (self.store.clone(), self.stage.as_ref()) {
            // A later stage: its group in the store the first stage made.
            let mut attrs = serde_json::Map::new();
            attrs.insert("scene".into(), info.scene.clone());
            attrs.insert("metrics".into(), serde_json::Value::Null);
            GroupBuilder::new()
                .attributes(attrs)
                .build(store.clone(), group)
                .map_err(|e| zerr(&path, e))?
                .store_metadata()
                .map_err(|e| zerr(&path, e))?;
            return self.create_arrays(info, &store, &prefix);
        }
        if path.exists() {
            std::fs::remove_dir_all(&path).map_err(|source| IoError::File {
                path: path.display().to_string(),
                source,
            })?;
        }
        std::fs::create_dir_all(&path).map_err(|source| IoError::File {
            path: path.display().to_string(),
            source,
        })?;
        let store = Arc::new(FilesystemStore::new(&path).map_err(|e| zerr(&path, e))?);
        let mut attrs = serde_json::Map::new();
        let scene = self.stage.as_ref().map_or(info.scene, |(_, whole)| whole);
        attrs.insert("scene".into(), scene.clone());
        attrs.insert("mpm_version".into(), mpm_core::VERSION.into());
        attrs.insert("dimension".into(), info.dimension.into());
        attrs.insert("particles".into(), info.particles.into());
        attrs.insert("metrics".into(), serde_json::Value::Null);
        let root = GroupBuilder::new()
            .attributes(attrs)
            .build(store.clone(), "/")
            .map_err(|e| zerr(&path, e))?;
        root.store_metadata().map_err(|e| zerr(&path, e))?;
        self.root = Some(root);
        self.store = Some(store.clone());
        if let Some((group, _)) = &self.stage {
            for g in ["/stages".to_string(), group.clone()] {
                let mut attrs = serde_json::Map::new();
                if &g == group {
                    attrs.insert("scene".into(), info.scene.clone());
                    attrs.insert("metrics".into(), serde_json::Value::Null);
                }
                GroupBuilder::new()
                    .attributes(attrs)
                    .build(store.clone(), &g)
                    .map_err(|e| zerr(&path, e))?
                    .store_metadata()
                    .map_err(|e| zerr(&path, e))?;
            }
        }
        self.create_arrays(info, &store, &prefix)
    }

    /// The per-frame arrays of a run (or stage) under `prefix`.
    fn create_arrays(
        &mut self,
        info: &RunInfo<'_>,
        store: &Arc<FilesystemStore>,
        prefix: &str,
    ) -> Result<(), IoError> {
        let path = self.path.clone();
        self.frames = 0;
        self.fields.clear();
        for group in [
            format!("{prefix}/particles"),
            format!("{prefix}/diagnostics"),
        ] {
            GroupBuilder::new()
                .build(store.clone(), &group)
                .map_err(|e| zerr(&path, e))?
                .store_metadata()
                .map_err(|e| zerr(&path, e))?;
        }
        let scalar = |name: &str| -> Result<Array<FilesystemStore>, IoError> {
            let array = ArrayBuilder::new(
                vec![0u64],
                vec![SCALAR_CHUNK],
                data_type::float64(),
                f64::NAN,
            )
            .bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false))])
            .dimension_names(Some(["frame"]))
            .build(store.clone(), name)
            .map_err(|e| zerr(&path, e))?;
            array.store_metadata().map_err(|e| zerr(&path, e))?;
            Ok(array)
        };
        self.time = Some(scalar(&format!("{prefix}/time"))?);
        self.diagnostics = FRAME_DIAGNOSTICS
            .iter()
            .map(|name| scalar(&format!("{prefix}/diagnostics/{name}")))
            .collect::<Result<_, _>>()?;
        let n = info.particles as u64;
        for field in info.fields {
            let mut shape = vec![0u64, n];
            shape.extend(field.shape.iter().map(|&s| s as u64));
            let mut chunk = shape.clone();
            chunk[0] = 1;
            let mut dims = vec!["frame".to_string(), "particle".to_string()];
            let component_names = ["component", "column"];
            for k in 0..field.shape.len() {
                dims.push(component_names.get(k).unwrap_or(&"extra").to_string());
            }
            let array = ArrayBuilder::new(shape.clone(), chunk, data_type::float64(), f64::NAN)
                .bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false))])
                .dimension_names(Some(dims))
                .build(store.clone(), &format!("{prefix}/particles/{}", field.name))
                .map_err(|e| zerr(&path, e))?;
            array.store_metadata().map_err(|e| zerr(&path, e))?;
            self.fields.push((array, shape));
        }
        Ok(())
    }

    fn append(&mut self, frame: &Frame<'_>) -> Result<(), IoError> {
        let path = self.path.clone();
        let k = self.frames;
        for (i, (array, shape)) in self.fields.iter_mut().enumerate() {
            shape[0] = k + 1;
            array.set_shape(shape.clone()).map_err(|e| zerr(&path, e))?;
            let mut chunk = vec![0u64; shape.len()];
            chunk[0] = k;
            array
                .store_chunk(&chunk, frame.values[i].as_slice())
                .map_err(|e| zerr(&path, e))?;
            array.store_metadata().map_err(|e| zerr(&path, e))?;
        }
        let scalars = std::iter::once((self.time.as_mut().expect("begun"), frame.time)).chain(
            self.diagnostics
                .iter_mut()
                .zip(frame.diagnostics.iter().copied()),
        );
        for (array, value) in scalars {
            array.set_shape(vec![k + 1]).map_err(|e| zerr(&path, e))?;
            let element =
                ArraySubset::new_with_start_shape(vec![k], vec![1]).map_err(|e| zerr(&path, e))?;
            array
                .store_array_subset(&element, &[value])
                .map_err(|e| zerr(&path, e))?;
            array.store_metadata().map_err(|e| zerr(&path, e))?;
        }
        self.frames += 1;
        Ok(())
    }
}

impl OutputSink for ZarrSink {
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError> {
        // Only the run (stage) the checkpoint was written in continues; later stages of a
        // resumed staged run are written afresh.
        match self.resume_after.take() {
            Some(frames) => self.reopen(info, frames).map_err(out),
            None => self.create(info).map_err(out),
        }
    }

    fn write_checkpoint(
        &mut self,
        checkpoint: &mpm_core::checkpoint::Checkpoint,
    ) -> Result<(), OutputError> {
        let (Some(store), Some(root)) = (self.store.as_ref(), self.root.as_mut()) else {
            return Ok(());
        };
        crate::checkpoint_store::write(store, root, &self.path, checkpoint).map_err(out)
    }

    fn write_stage_end(
        &mut self,
        state: &mpm_core::checkpoint::Checkpoint,
    ) -> Result<(), OutputError> {
        let (Some(store), Some((group, _))) = (self.store.as_ref(), self.stage.as_ref()) else {
            return Ok(());
        };
        crate::checkpoint_store::write_stage_end(store, &self.path, group, state).map_err(out)
    }

    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        self.append(frame).map_err(out)
    }

    fn finish(&mut self, metrics: &Metrics) -> Result<(), OutputError> {
        let path = self.path.clone();
        let value = serde_json::to_value(metrics).map_err(|e| OutputError(e.to_string()))?;
        if let (Some(store), Some((group, _))) = (self.store.as_ref(), self.stage.as_ref()) {
            let mut g = Group::open(store.clone(), group).map_err(|e| out(zerr(&path, e)))?;
            g.attributes_mut().insert("metrics".into(), value.clone());
            g.store_metadata().map_err(|e| out(zerr(&path, e)))?;
        }
        let Some(root) = self.root.as_mut() else {
            return Ok(());
        };
        root.attributes_mut().insert("metrics".into(), value);
        root.store_metadata().map_err(|e| out(zerr(&path, e)))?;
        // After the metrics, so a table that cannot be written loses nothing else.
        self.write_tables(&metrics.tables).map_err(out)
    }

    fn begin_stage(&mut self, stage: &StageInfo<'_>) -> Result<(), OutputError> {
        self.stage = Some((
            format!("/stages/{}-{}", stage.index, stage.name),
            stage.scene.clone(),
        ));
        Ok(())
    }

    fn finish_stages(&mut self, metrics: &Metrics) -> Result<(), OutputError> {
        let path = self.path.clone();
        let Some(root) = self.root.as_mut() else {
            return Ok(());
        };
        let value = serde_json::to_value(metrics).map_err(|e| OutputError(e.to_string()))?;
        root.attributes_mut().insert("metrics".into(), value);
        root.store_metadata().map_err(|e| out(zerr(&path, e)))
    }
}

impl ZarrSink {
    /// Writes each table as the float64 array `tables/<name>`, `[row, column]`, one chunk,
    /// with its column names in the attribute `columns` (no `tables` group without tables).
    fn write_tables(&self, tables: &BTreeMap<String, Table>) -> Result<(), IoError> {
        let (Some(store), false) = (self.store.as_ref(), tables.is_empty()) else {
            return Ok(());
        };
        let path = &self.path;
        let layout = |message: String| IoError::Layout {
            path: path.display().to_string(),
            message,
        };
        for (name, table) in tables {
            if !valid_table_name(name) {
                return Err(layout(format!(
                    "table name `{name}` cannot name a Zarr array (empty, `/`, `.`, `..` or `__`)"
                )));
            }
            let width = table.columns.len();
            if let Some((i, row)) = table
                .rows
                .iter()
                .enumerate()
                .find(|(_, r)| r.len() != width)
            {
                return Err(layout(format!(
                    "table `{name}` row {i} has {} numbers for {width} columns",
                    row.len()
                )));
            }
        }
        let prefix = self.prefix();
        GroupBuilder::new()
            .build(store.clone(), &format!("{prefix}/tables"))
            .map_err(|e| zerr(path, e))?
            .store_metadata()
            .map_err(|e| zerr(path, e))?;
        for (name, table) in tables {
            let shape = vec![table.rows.len() as u64, table.columns.len() as u64];
            // Chunk extents must be positive; an empty table stores no chunk at all.
            let chunk: Vec<u64> = shape.iter().map(|&s| s.max(1)).collect();
            let mut attrs = serde_json::Map::new();
            attrs.insert("columns".into(), table.columns.clone().into());
            let array = ArrayBuilder::new(shape.clone(), chunk, data_type::float64(), f64::NAN)
                .bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false))])
                // Dimensions named per table: tables of different lengths share a group,
                // and xarray (a DataTree) needs each length under its own name.
                .dimension_names(Some([format!("{name}_row"), format!("{name}_column")]))
                .attributes(attrs)
                .build(store.clone(), &format!("{prefix}/tables/{name}"))
                .map_err(|e| zerr(path, e))?;
            array.store_metadata().map_err(|e| zerr(path, e))?;
            if shape.iter().all(|&s| s > 0) {
                let values: Vec<f64> = table.rows.concat();
                array
                    .store_chunk(&[0, 0], values.as_slice())
                    .map_err(|e| zerr(path, e))?;
            }
        }
        Ok(())
    }
}

/// Whether `name` can be a Zarr array name under `tables/`.
pub(crate) fn valid_table_name(name: &str) -> bool {
    !name.is_empty()
        && !name.contains('/')
        && name != "."
        && name != ".."
        && !name.starts_with("__")
}
