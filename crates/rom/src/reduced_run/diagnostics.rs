//! The diagnostics with which a reduced run stops.

use mpm_core::output::Diagnostic;

/// A diagnostic without step and time (filled in by [`diagnostic_at`]).
pub(super) fn diagnostic(particle: usize, field: &str, value: f64, message: &str) -> Diagnostic {
    Diagnostic {
        step: 0,
        time: 0.0,
        particle: Some(particle),
        field: field.into(),
        value,
        message: message.into(),
    }
}

/// A diagnostic of no particle.
pub(super) fn diagnostic_plain(field: &str, value: f64, message: &str) -> Diagnostic {
    Diagnostic {
        particle: None,
        ..diagnostic(0, field, value, message)
    }
}

/// `d` at `step` and `time`.
pub(super) fn diagnostic_at(step: u64, time: f64, d: Diagnostic) -> Diagnostic {
    Diagnostic { step, time, ..d }
}
