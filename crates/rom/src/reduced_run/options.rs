//! The settings of a reduced run (`mpm rom run`) and the output fields it can write.

/// Settings of `mpm rom run`.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Sampled particles N at which the MPM update is done.
    pub samples: usize,
    /// Multiplies the scene's time step (1: the full-order step).
    pub time_step_scale: f64,
    /// Extra reach, in cells, of the candidate neighbourhood around each sample beyond the
    /// kernel's, for particles that come closer as the body deforms.
    pub margin: f64,
    /// Gauss–Newton iterations of the projection (the linear map needs one).
    pub projection_iterations: usize,
    /// Sample only particles at least a cell inside the body (see
    /// [`interior_particles`](super::sampling::interior_particles)).
    pub interior_samples: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            samples: 32,
            time_step_scale: 1.0,
            margin: 1.0,
            projection_iterations: 3,
            interior_samples: true,
        }
    }
}

/// Output fields a reduced run can write.
pub const REDUCED_FIELDS: &[&str] = &["x", "v", "F", "J", "stress", "mass", "volume", "material"];
