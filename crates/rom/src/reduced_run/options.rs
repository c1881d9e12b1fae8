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
    /// How the samples are picked among the eligible particles.
    pub sampling: Sampling,
}

/// How a reduced run picks its sampled particles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sampling {
    /// Spread over the body: farthest-point sampling in the reference configuration.
    #[default]
    FarthestPoint,
    /// Chosen from the map's modes: each pick makes the projection's normal matrix best
    /// conditioned (greedy D-optimal design, see
    /// [`greedy_samples`](super::sampling_greedy::greedy_samples)).
    Greedy,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            samples: 32,
            time_step_scale: 1.0,
            margin: 1.0,
            projection_iterations: 3,
            interior_samples: true,
            sampling: Sampling::FarthestPoint,
        }
    }
}

/// Output fields a reduced run can write.
pub const REDUCED_FIELDS: &[&str] = &["x", "v", "F", "J", "stress", "mass", "volume", "material"];
