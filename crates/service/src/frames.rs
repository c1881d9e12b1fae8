//! Pictures of a job's frames: the service knows no physics and draws nothing itself; the
//! binary passes in a [`FrameRenderer`] (the `mpm render` drawing) through
//! [`Config::frame_renderer`](crate::Config::frame_renderer).

use std::path::Path;

/// Which picture of a store to draw.
#[derive(Clone, Debug)]
pub struct FrameRequest {
    /// Particle field to colour by.
    pub field: String,
    /// Frame index; negative counts from the end (-1: the last).
    pub frame: i64,
    /// Flat component index of a vector or tensor field.
    pub component: usize,
}

/// Why a picture could not be drawn.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The request does not fit the store (no such field or frame, a 3D store): a 4xx.
    Invalid(String),
    /// Drawing failed for another reason (an unreadable store): a 500.
    Failed(String),
}

/// Draws one frame of a 2D result store as PNG bytes.
pub trait FrameRenderer: Send + Sync + std::fmt::Debug {
    /// The PNG of `request` drawn from the store at `store`. Must return an error, never
    /// panic, on any store or request.
    fn render_png(&self, store: &Path, request: &FrameRequest) -> Result<Vec<u8>, FrameError>;
}
