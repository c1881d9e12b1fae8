//! Result stores in a folder shared by the API and every worker: jobs write in place and the
//! API reads the files.

use super::StoreError;
use std::path::{Path, PathBuf};

/// A folder of `<id>/results.zarr` stores.
#[derive(Debug)]
pub(crate) struct LocalStore {
    /// The folder.
    pub root: PathBuf,
}

impl LocalStore {
    /// Creates the folder if needed.
    pub fn open(root: &Path) -> Result<Self, StoreError> {
        std::fs::create_dir_all(root).map_err(|e| StoreError::io(root, e))?;
        Ok(Self {
            root: root.to_path_buf(),
        })
    }

    /// The file `key` of the store at `store`; `None` when missing.
    pub async fn read(&self, store: &Path, key: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let path = store.join(key);
        match tokio::fs::read(&path).await {
            Ok(bytes) => Ok(Some(bytes)),
            // A missing file, or a folder asked for as a file: not a key of the store.
            Err(_) => Ok(None),
        }
    }
}

/// Every file under `root` as a sorted `/`-separated path relative to it (empty when the
/// folder does not exist).
pub(crate) async fn list_files(root: PathBuf) -> Result<Vec<String>, StoreError> {
    tokio::task::spawn_blocking(move || walk(&root))
        .await
        .map_err(|e| StoreError::Io {
            path: "listing a store".into(),
            error: std::io::Error::other(e),
        })
}

/// The files under `root` with their relative paths, sorted.
pub(crate) fn walk(root: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if let Ok(rel) = path.strip_prefix(root) {
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out.sort();
    out
}
