//! The job service's frame pictures (`GET /v1/jobs/{id}/frames/{frame}`), drawn by
//! [`render`](super::render) exactly as `mpm render` draws them.

use super::{RenderArgs, render};
use crate::exit_status::InputError;
use mpm_service::{FrameError, FrameRenderer, FrameRequest};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Draws frames for the service through a temporary PNG file (the drawing writes files).
#[derive(Debug, Default)]
pub struct ServiceRenderer;

/// A PNG file name no other picture of this process uses, in the system's temporary folder.
fn scratch_file() -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("mpm-frame-{}-{n}.png", std::process::id()))
}

impl FrameRenderer for ServiceRenderer {
    fn render_png(&self, store: &Path, request: &FrameRequest) -> Result<Vec<u8>, FrameError> {
        let out = scratch_file();
        let args = RenderArgs {
            store: store.to_path_buf(),
            field: request.field.clone(),
            frame: Some(request.frame),
            component: request.component,
            out: out.clone(),
            title: None,
            voids: None,
            stage: None,
            plane: None,
            slab: None,
            deformed: false,
            hide_levels: false,
        };
        let drawn = render(&args);
        let bytes = std::fs::read(&out);
        let _ = std::fs::remove_file(&out);
        // Messages name the store's folder on the server; the caller knows it as its job's.
        let hide = |e: &anyhow::Error| {
            format!("{e:#}").replace(&store.display().to_string(), "the job's results")
        };
        match drawn {
            Ok(_) => bytes.map_err(|e| FrameError::Failed(format!("reading the picture: {e}"))),
            Err(e) if e.chain().any(|c| c.is::<InputError>()) => Err(FrameError::Invalid(hide(&e))),
            Err(e) => Err(FrameError::Failed(hide(&e))),
        }
    }
}
