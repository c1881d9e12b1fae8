//! The model file: one safetensors file of float64 arrays, with the model's description as
//! JSON in the header metadata under `mpm_rom`. Python reads it with the `safetensors`
//! package (`safetensors.numpy.load_file`).

use crate::RomError;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use std::collections::HashMap;
use std::path::Path;

/// Metadata key that holds the model description.
pub const METADATA_KEY: &str = "mpm_rom";

/// One named float64 array of a model file.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedArray {
    /// Name in the file.
    pub name: String,
    /// Shape (row-major).
    pub shape: Vec<usize>,
    /// Values, row-major.
    pub data: Vec<f64>,
}

impl NamedArray {
    /// An array; `data.len()` must equal the product of `shape`.
    pub fn new(name: impl Into<String>, shape: Vec<usize>, data: Vec<f64>) -> Self {
        Self {
            name: name.into(),
            shape,
            data,
        }
    }
}

fn file_error(path: &Path, message: impl std::fmt::Display) -> RomError {
    RomError::File {
        path: path.display().to_string(),
        message: message.to_string(),
    }
}

fn bad(path: &Path, message: impl std::fmt::Display) -> RomError {
    RomError::BadModel {
        path: path.display().to_string(),
        message: message.to_string(),
    }
}

/// Writes `arrays` and the description `info` (any JSON) to `path`.
pub fn save(path: &Path, info: &serde_json::Value, arrays: &[NamedArray]) -> Result<(), RomError> {
    let bytes: Vec<Vec<u8>> = arrays
        .iter()
        .map(|a| a.data.iter().flat_map(|v| v.to_le_bytes()).collect())
        .collect();
    let mut views = Vec::with_capacity(arrays.len());
    for (a, b) in arrays.iter().zip(&bytes) {
        let view = TensorView::new(Dtype::F64, a.shape.clone(), b)
            .map_err(|e| file_error(path, format!("array `{}`: {e}", a.name)))?;
        views.push((a.name.clone(), view));
    }
    let metadata = HashMap::from([(METADATA_KEY.to_string(), info.to_string())]);
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| file_error(parent, e))?;
    }
    safetensors::serialize_to_file(views, Some(metadata), path).map_err(|e| file_error(path, e))
}

/// Reads a model file: its description and its arrays.
pub fn load(path: &Path) -> Result<(serde_json::Value, Vec<NamedArray>), RomError> {
    let buffer = std::fs::read(path).map_err(|e| file_error(path, e))?;
    let (_, metadata) = SafeTensors::read_metadata(&buffer)
        .map_err(|e| bad(path, format!("not a safetensors file ({e})")))?;
    let text = metadata
        .metadata()
        .as_ref()
        .and_then(|m| m.get(METADATA_KEY))
        .ok_or_else(|| {
            bad(
                path,
                format!("no `{METADATA_KEY}` metadata: not a model written by `mpm rom train`"),
            )
        })?;
    let info: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| bad(path, format!("`{METADATA_KEY}` metadata is not JSON: {e}")))?;
    let tensors = SafeTensors::deserialize(&buffer).map_err(|e| bad(path, e))?;
    let mut arrays = Vec::new();
    for (name, view) in tensors.tensors() {
        if view.dtype() != Dtype::F64 {
            return Err(bad(path, format!("array `{name}` is not float64")));
        }
        let data = view
            .data()
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        arrays.push(NamedArray::new(name, view.shape().to_vec(), data));
    }
    arrays.sort_by(|a, b| a.name.cmp(&b.name));
    Ok((info, arrays))
}

/// Takes the array `name` out of `arrays`, checking its shape.
pub fn take(
    path: &Path,
    arrays: &mut Vec<NamedArray>,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f64>, RomError> {
    let index = arrays
        .iter()
        .position(|a| a.name == name)
        .ok_or_else(|| bad(path, format!("array `{name}` is missing")))?;
    let array = arrays.swap_remove(index);
    if array.shape != shape {
        return Err(bad(
            path,
            format!(
                "array `{name}` has shape {:?}, the description says {shape:?}",
                array.shape
            ),
        ));
    }
    Ok(array.data)
}
