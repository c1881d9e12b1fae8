//! Reading a scene file: read it, apply `--set` overrides, validate; and how a failure to
//! load is reported, shared by every command that takes a scene.

use crate::exit_status::ExitStatus;
use crate::overrides::apply_override;
use anyhow::Context;
use mpm_core::plugin::Registry;
use mpm_core::scene::{SceneError, ValidatedScene, parse_scene_value};
use std::path::Path;

/// A scene file that failed to load: unreadable, or invalid.
#[derive(Debug)]
pub enum LoadError {
    /// Could not read the file.
    Io(anyhow::Error),
    /// The scene is invalid.
    Invalid(SceneError),
}

/// Reads, overrides and validates a scene file.
pub fn load_scene(
    path: &Path,
    overrides: &[String],
    registry: &Registry,
) -> Result<ValidatedScene, LoadError> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read scene file `{}`", path.display()))
        .map_err(LoadError::Io)?;
    let mut value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| LoadError::Invalid(SceneError::single("$", format!("not valid JSON: {e}"))))?;
    for o in overrides {
        apply_override(&mut value, o)
            .map_err(|e| LoadError::Invalid(SceneError::single("--set", format!("{e:#}"))))?;
    }
    let base = path.parent().unwrap_or(Path::new("."));
    parse_scene_value(value, registry, base).map_err(LoadError::Invalid)
}

/// Prints why `path` did not load and returns the exit status for it.
pub(crate) fn report_load_error(path: &Path, e: LoadError) -> ExitStatus {
    match e {
        LoadError::Io(e) => {
            eprintln!("error: {e:#}");
            ExitStatus::Failure
        }
        LoadError::Invalid(e) => {
            eprintln!("error: {}: {e}", path.display());
            ExitStatus::InvalidInput
        }
    }
}
