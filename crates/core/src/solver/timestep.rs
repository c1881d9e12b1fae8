//! The stable explicit time step.

/// Largest stable step at Courant number 1: `dx / (max |v| + max c)`.
pub fn stable_time_step(dx: f64, max_speed: f64, max_wave_speed: f64) -> f64 {
    let speed = max_speed + max_wave_speed;
    if speed > 0.0 {
        dx / speed
    } else {
        f64::INFINITY
    }
}
