//! Checkpoints in the result store: group `checkpoints/<step>` with one float64 array per
//! named array of the [`Checkpoint`] (1D, chunks of 2^20 numbers, zstd) and the structured
//! state in the group's attribute `state`; the root attribute `checkpoint` names the latest
//! complete one. A new checkpoint is written beside the old one, then named in the root
//! attributes, then the old one is removed: a run killed while writing keeps the previous.

use crate::IoError;
use mpm_core::checkpoint::Checkpoint;
use std::path::Path;
use std::sync::Arc;
use zarrs::array::codec::ZstdCodec;
use zarrs::array::{Array, ArrayBuilder, data_type};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::{Group, GroupBuilder};

/// Numbers per chunk of a checkpoint array.
const CHUNK: u64 = 1 << 20;

fn zerr(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Zarr {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

fn layout(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Layout {
        path: path.display().to_string(),
        message: message.into(),
    }
}

/// Writes `c` into the store at `path` and makes it the latest checkpoint.
pub(crate) fn write(
    store: &Arc<FilesystemStore>,
    root: &mut Group<FilesystemStore>,
    path: &Path,
    c: &Checkpoint,
) -> Result<(), IoError> {
    let step = c.state("step").as_u64().unwrap_or(0);
    let name = format!("checkpoints/{step}");
    if !path.join("checkpoints").join("zarr.json").is_file() {
        GroupBuilder::new()
            .build(store.clone(), "/checkpoints")
            .map_err(|e| zerr(path, e))?
            .store_metadata()
            .map_err(|e| zerr(path, e))?;
    }
    write_group(store, path, &format!("/{name}"), c)?;
    let pointer = serde_json::json!({
        "path": name,
        "step": step,
        "time": c.state("time"),
        "frames": c.state("frames"),
    });
    root.attributes_mut().insert("checkpoint".into(), pointer);
    root.store_metadata().map_err(|e| zerr(path, e))?;
    // The new checkpoint is complete and named: the older ones go.
    let dir = path.join("checkpoints");
    if let Ok(entries) = std::fs::read_dir(&dir) {
        for entry in entries.filter_map(Result::ok) {
            let keep = entry.file_name().to_str() == Some(&step.to_string());
            if !keep && entry.path().is_dir() {
                std::fs::remove_dir_all(entry.path()).map_err(|source| IoError::File {
                    path: entry.path().display().to_string(),
                    source,
                })?;
            }
        }
    }
    Ok(())
}

/// Writes `c` as the group `group_path` of the store at `path`: one float64 array per named
/// array, the structured state in the group's attribute `state`.
fn write_group(
    store: &Arc<FilesystemStore>,
    path: &Path,
    group_path: &str,
    c: &Checkpoint,
) -> Result<(), IoError> {
    let mut attrs = serde_json::Map::new();
    attrs.insert("state".into(), c.state.clone());
    let names: Vec<&String> = c.arrays.keys().collect();
    attrs.insert(
        "arrays".into(),
        serde_json::to_value(&names).unwrap_or_default(),
    );
    let group = GroupBuilder::new()
        .attributes(attrs)
        .build(store.clone(), group_path)
        .map_err(|e| zerr(path, e))?;
    group.store_metadata().map_err(|e| zerr(path, e))?;
    for (array_name, values) in &c.arrays {
        let n = values.len() as u64;
        let array = ArrayBuilder::new(
            vec![n],
            vec![n.clamp(1, CHUNK)],
            data_type::float64(),
            f64::NAN,
        )
        .bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false))])
        .dimension_names(Some([array_name.as_str()]))
        .build(store.clone(), &format!("{group_path}/{array_name}"))
        .map_err(|e| zerr(path, e))?;
        array.store_metadata().map_err(|e| zerr(path, e))?;
        if n > 0 {
            array
                .store_array_subset(&array.subset_all(), values.as_slice())
                .map_err(|e| zerr(path, e))?;
        }
    }
    Ok(())
}

/// Name of the group, inside a stage's group, that keeps the state the stage ended with.
pub const STAGE_END: &str = "end_state";

/// Writes `c`, the state a finished stage left, into that stage's group `stage_group`
/// (`/stages/<index>-<name>`) as `end_state`, so a later run can start at the next stage.
pub(crate) fn write_stage_end(
    store: &Arc<FilesystemStore>,
    path: &Path,
    stage_group: &str,
    c: &Checkpoint,
) -> Result<(), IoError> {
    write_group(store, path, &format!("{stage_group}/{STAGE_END}"), c)
}

/// Reads the latest checkpoint of the store at `path`.
pub fn read_checkpoint(path: &Path) -> Result<Checkpoint, IoError> {
    if !path.join("zarr.json").is_file() {
        return Err(layout(path, "not a Zarr v3 store (no zarr.json)"));
    }
    let store = Arc::new(FilesystemStore::new(path).map_err(|e| zerr(path, e))?);
    let root = Group::open(store.clone(), "/").map_err(|e| zerr(path, e))?;
    let pointer = root.attributes().get("checkpoint").cloned().ok_or_else(|| {
        layout(
            path,
            "the store has no checkpoint (run the scene with `output.checkpoint` to write them)",
        )
    })?;
    let name = pointer
        .get("path")
        .and_then(|p| p.as_str())
        .filter(|p| {
            p.strip_prefix("checkpoints/")
                .is_some_and(|s| !s.is_empty() && s.chars().all(|c| c.is_ascii_digit()))
        })
        .ok_or_else(|| {
            layout(
                path,
                format!("the checkpoint attribute {pointer} is damaged"),
            )
        })?;
    read_group(&store, path, &format!("/{name}"))
}

/// Reads the state a finished stage left: the group `end_state` of the stage group
/// `/stages/<index>-<name>` of the store at `path` (written only by a stage with
/// `output.end_state` or `output.checkpoint`).
pub fn read_stage_end(path: &Path, index: usize, name: &str) -> Result<Checkpoint, IoError> {
    if !path.join("zarr.json").is_file() {
        return Err(layout(path, "not a Zarr v3 store (no zarr.json)"));
    }
    let group = format!("stages/{index}-{name}/{STAGE_END}");
    if !path.join(&group).join("zarr.json").is_file() {
        return Err(layout(
            path,
            format!(
                "the store keeps no end state of stage {index} `{name}` (the stage did not \
                 finish, or ran without `output.end_state` or `output.checkpoint`)"
            ),
        ));
    }
    let store = Arc::new(FilesystemStore::new(path).map_err(|e| zerr(path, e))?);
    read_group(&store, path, &format!("/{group}"))
}

/// Reads the checkpoint kept as the group `name` of the store at `path`.
fn read_group(
    store: &Arc<FilesystemStore>,
    path: &Path,
    name: &str,
) -> Result<Checkpoint, IoError> {
    let group = Group::open(store.clone(), name).map_err(|e| zerr(path, e))?;
    let attrs = group.attributes();
    let state = attrs.get("state").cloned().unwrap_or_default();
    let names: Vec<String> = attrs
        .get("arrays")
        .and_then(|a| serde_json::from_value(a.clone()).ok())
        .ok_or_else(|| layout(path, format!("{name} lists no arrays")))?;
    let mut c = Checkpoint {
        state,
        ..Checkpoint::default()
    };
    for array_name in names {
        if array_name.is_empty() || array_name.contains('/') || array_name.starts_with("__") {
            return Err(layout(
                path,
                format!("{name}: bad array name `{array_name}`"),
            ));
        }
        let array = Array::open(store.clone(), &format!("{name}/{array_name}"))
            .map_err(|e| zerr(path, e))?;
        let values = if array.shape().first().copied().unwrap_or(0) == 0 {
            Vec::new()
        } else {
            array
                .retrieve_array_subset::<Vec<f64>>(&array.subset_all())
                .map_err(|e| zerr(path, e))?
        };
        c.put(array_name, values);
    }
    Ok(c)
}
