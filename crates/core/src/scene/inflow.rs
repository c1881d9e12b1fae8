//! The `inflow` body shape: liquid that enters the domain through an inlet (the feed of an
//! edge bead, a dispense needle moving along a line) at a set volume flow rate, or from a
//! reservoir held at a set pressure.
//!
//! The body's particles are all made at the start, as layers of a lattice across the
//! inlet face, and wait there without mass (the `injected` field is 0). At a set `rate`,
//! layer j enters at t_j = start + (j + ½)·h/U, when its centres would cross the face
//! moving at U; U is the rate over the lattice's area across the face, so the volume
//! entered by time t is the rate times (t − start) to within half a layer. At a set
//! `pressure` the reservoir holds `volume` (the layers made) and the liquid at the face
//! sets when each layer enters (`solver/incompressible/pressure_inlet.rs`). The
//! incompressible mode moves them in (`solver/incompressible/inflow.rs`).

use super::Scene;
use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Particle field of scenes with an inflow body or `outflow`: 1 for a particle in the
/// liquid, 0 for one still waiting at its inlet, −1 for one that left through an open
/// face (both without mass, left out of every sum).
pub const INJECTED: &str = "injected";

/// An inlet that liquid particles enter through at a set volume flow rate (`rate`) or from
/// a reservoir at a set pressure (`pressure` and `volume`).
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Inflow {
    /// Centre of the inlet face at `start`.
    pub center: Vec<f64>,
    /// Direction the liquid enters along (normalised on use).
    pub direction: Vec<f64>,
    /// Width of the inlet across `direction`: a segment in 2D, a square of this side in
    /// 3D. Give this or `radius`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<f64>,
    /// 3D only: a round inlet (a needle) of this radius instead of a square.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Volume flow rate, m³/s (in 2D m²/s, per metre of depth). Give this or `pressure`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<f64>,
    /// Gauge pressure of the reservoir behind the inlet face, Pa: the face is held at it
    /// while the flow lasts and the liquid enters as fast as it moves away from the face.
    /// Give this or `rate`; with it, `volume`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pressure: Option<f64>,
    /// With `pressure`: the liquid the reservoir holds, m³ (in 2D m² per metre of depth);
    /// the flow stops when it has all entered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume: Option<f64>,
    /// Time the flow starts, s.
    #[serde(default)]
    pub start: f64,
    /// Time the flow stops, s (default: the scene's end time).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end: Option<f64>,
    /// Velocity of the inlet itself, m/s (a needle moving along a line); the liquid leaves
    /// it with this velocity added. Default: at rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<Vec<f64>>,
}

/// Where an inflow's particles wait and when each layer enters.
#[derive(Clone, Debug, PartialEq)]
pub struct InflowLayout {
    /// Offsets of the lattice points across the inlet face from its centre.
    pub offsets: Vec<[f64; 3]>,
    /// Unit direction of entry.
    pub direction: [f64; 3],
    /// The inlet's own velocity.
    pub inlet_velocity: [f64; 3],
    /// Entry speed U along `direction`: the rate over the lattice's area across the face
    /// (0 for a pressure inlet, whose speed the liquid sets).
    pub speed: f64,
    /// The reservoir's gauge pressure of a pressure inlet, Pa (`None` at a set rate).
    pub pressure: Option<f64>,
    /// Time the flow stops.
    pub end: f64,
    /// Half the inlet's extent across the face (half its width, or its radius).
    pub half_width: f64,
    /// Whether the inlet is round (3D, `radius`).
    pub round: bool,
    /// The two unit tangents of the face the lattice is laid along (the second is zero
    /// in 2D).
    pub tangents: [[f64; 3]; 2],
    /// Layers that enter before `end`.
    pub layers: usize,
    /// Particle spacing h.
    pub spacing: f64,
    /// Start of the flow.
    pub start: f64,
    /// Centre of the inlet at `start`.
    pub center: [f64; 3],
}

impl InflowLayout {
    /// Time layer `layer` of a rate inlet enters (its centres cross the inlet face); a
    /// pressure inlet's layers wait at the face's place at `start`.
    pub fn entry_time(&self, layer: usize) -> f64 {
        if self.pressure.is_some() {
            return self.start;
        }
        self.start + (layer as f64 + 0.5) * self.spacing / self.speed
    }

    /// Whether `x` lies across the inlet face from its centre `c` (within half a cell `dx`
    /// beyond its edge) and within `behind` before to `ahead` past the face along the
    /// direction: the nodes a pressure inlet holds and the particles its speed is read from.
    pub fn reaches(&self, c: &[f64; 3], x: &[f64; 3], behind: f64, ahead: f64, dx: f64) -> bool {
        let mut r = [0.0; 3];
        for a in 0..3 {
            r[a] = x[a] - c[a];
        }
        let along: f64 = (0..3).map(|a| r[a] * self.direction[a]).sum();
        if along < -behind || along >= ahead {
            return false;
        }
        let across2: f64 = (0..3)
            .map(|a| (r[a] - along * self.direction[a]).powi(2))
            .sum();
        let reach = self.half_width + 0.5 * dx;
        if self.round {
            return across2 <= reach * reach;
        }
        // A square inlet: each tangent component within reach (in 2D the second tangent
        // is zero).
        let [t1, t2] = self.tangents;
        let a1: f64 = (0..3).map(|a| r[a] * t1[a]).sum();
        let a2: f64 = (0..3).map(|a| r[a] * t2[a]).sum();
        a1.abs() <= reach && a2.abs() <= reach
    }

    /// Centre of the inlet face at time `t` (≥ start).
    pub fn center_at(&self, t: f64) -> [f64; 3] {
        let mut c = self.center;
        for (ci, vi) in c.iter_mut().zip(self.inlet_velocity) {
            *ci += vi * (t - self.start);
        }
        c
    }

    /// Velocity a particle enters with: U along the direction plus the inlet's own.
    pub fn entry_velocity(&self) -> [f64; 3] {
        let mut v = self.inlet_velocity;
        for (vi, ni) in v.iter_mut().zip(self.direction) {
            *vi += self.speed * ni;
        }
        v
    }

    /// Particles of the whole inflow (layers × lattice points across the face).
    pub fn particles(&self) -> usize {
        self.layers * self.offsets.len()
    }
}

/// Two unit vectors across `n` (3D; the second is zero in 2D).
fn across(dim: usize, n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    if dim == 2 {
        return ([-n[1], n[0], 0.0], [0.0; 3]);
    }
    // The coordinate axis least aligned with n, crossed with n.
    let k = (0..3)
        .min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
        .unwrap_or(0);
    let mut e = [0.0; 3];
    e[k] = 1.0;
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let t1 = cross(n, e);
    let norm = t1.iter().map(|x| x * x).sum::<f64>().sqrt();
    let t1 = [t1[0] / norm, t1[1] / norm, t1[2] / norm];
    (t1, cross(n, t1))
}

impl Inflow {
    /// The end of the flow in a scene that ends at `end_time`.
    pub fn end_time(&self, end_time: f64) -> f64 {
        self.end.unwrap_or(end_time)
    }

    /// The volume the inlet supplies in a scene ending at `end_time`: the rate times the
    /// flow's duration, or the reservoir's volume (NaN when neither is given).
    fn supplied_volume(&self, end_time: f64) -> f64 {
        match (self.rate, self.volume) {
            (Some(rate), _) => rate * (self.end_time(end_time) - self.start),
            (None, Some(volume)) => volume,
            (None, None) => f64::NAN,
        }
    }

    /// Lattice points across the face along one tangent (at least one).
    fn points_across(&self, h: f64) -> usize {
        let extent = self.width.or(self.radius.map(|r| 2.0 * r)).unwrap_or(h);
        ((extent / h).round() as usize).max(1)
    }

    /// Particles the inflow makes with spacing `h` in a scene ending at `end_time`,
    /// without making them (for the work budget); 0 for malformed numbers.
    pub(super) fn particle_estimate(&self, dim: usize, h: f64, end_time: f64) -> f64 {
        let n = self.points_across(h) as f64;
        let face = if dim == 2 {
            n
        } else if self.radius.is_some() {
            (std::f64::consts::FRAC_PI_4 * n * n).max(1.0)
        } else {
            n * n
        };
        let area = face * h.powi(dim as i32 - 1);
        let layers = (self.supplied_volume(end_time) / area / h).max(0.0);
        if layers.is_finite() {
            layers * face
        } else {
            0.0
        }
    }

    /// The lattice across the face and the entry schedule with spacing `h`, for a scene
    /// ending at `end_time`. Assumes a validated inflow.
    pub fn layout(&self, dim: usize, h: f64, end_time: f64) -> InflowLayout {
        let mut direction = [0.0; 3];
        let norm = self.direction.iter().map(|x| x * x).sum::<f64>().sqrt();
        for (d, x) in direction.iter_mut().zip(&self.direction) {
            *d = x / norm;
        }
        let (t1, t2) = across(dim, direction);
        let n = self.points_across(h);
        let centred = |i: usize| (i as f64 + 0.5 - n as f64 / 2.0) * h;
        let mut offsets = Vec::new();
        let second = if dim == 2 { 1 } else { n };
        for i in 0..n {
            for j in 0..second {
                let (a, b) = (centred(i), if dim == 2 { 0.0 } else { centred(j) });
                if let Some(r) = self.radius
                    && a * a + b * b > r * r
                {
                    continue;
                }
                offsets.push(std::array::from_fn(|k| a * t1[k] + b * t2[k]));
            }
        }
        if offsets.is_empty() {
            offsets.push([0.0; 3]);
        }
        let area = offsets.len() as f64 * h.powi(dim as i32 - 1);
        let speed = self.rate.map_or(0.0, |rate| rate / area);
        let layers = (self.supplied_volume(end_time) / area / h + 0.5)
            .floor()
            .max(0.0);
        let layers = if layers.is_finite() {
            layers as usize
        } else {
            0
        };
        let mut center = [0.0; 3];
        center[..dim].copy_from_slice(&self.center[..dim]);
        let mut inlet_velocity = [0.0; 3];
        if let Some(v) = &self.velocity {
            inlet_velocity[..dim].copy_from_slice(&v[..dim]);
        }
        InflowLayout {
            offsets,
            direction,
            inlet_velocity,
            speed,
            pressure: if self.rate.is_some() {
                None
            } else {
                self.pressure
            },
            end: self.end_time(end_time),
            half_width: self.width.map_or(self.radius.unwrap_or(0.0), |w| 0.5 * w),
            round: self.radius.is_some(),
            tangents: [t1, t2],
            layers,
            spacing: h,
            start: self.start,
            center,
        }
    }

    /// Checks an inflow shape at `path` (`bodies[0].shape.inflow`) of a body with spacing
    /// `h` in scene `s`.
    pub(super) fn validate(&self, v: &mut Validator, path: &str, s: &Scene, h: f64) {
        let dim = v.dim;
        let mut ok = v.vector(&format!("{path}.center"), &self.center);
        v.nonzero_vector(&format!("{path}.direction"), &self.direction);
        ok &= self.direction.len() == dim && self.direction.iter().any(|x| *x != 0.0);
        if let Some(velocity) = &self.velocity {
            ok &= v.vector(&format!("{path}.velocity"), velocity);
        }
        match (self.width, self.radius) {
            (Some(w), None) => v.positive(&format!("{path}.width"), w),
            (None, Some(r)) if dim == 3 => v.positive(&format!("{path}.radius"), r),
            (None, Some(_)) => v.err(
                format!("{path}.radius"),
                "a round inlet is 3D; give `width` in 2D",
            ),
            _ => v.err(
                path,
                "give the inlet's `width` or (3D) its `radius`, one of them",
            ),
        }
        let extent = self.width.or(self.radius.map(|r| 2.0 * r)).unwrap_or(0.0);
        ok &= extent.is_finite() && extent > 0.0;
        if extent / h > super::lattice::MAX_SPACINGS {
            v.err(
                path,
                format!("the inlet spans {:.3e} particle spacings", extent / h),
            );
            ok = false;
        }
        match (self.rate, self.pressure, self.volume) {
            (Some(rate), None, None) => {
                v.positive(&format!("{path}.rate"), rate);
                ok &= rate.is_finite() && rate > 0.0;
            }
            (None, Some(pressure), Some(volume)) => {
                if !pressure.is_finite() {
                    v.err(
                        format!("{path}.pressure"),
                        "must be a finite gauge pressure, Pa",
                    );
                    ok = false;
                }
                v.positive(&format!("{path}.volume"), volume);
                ok &= volume.is_finite() && volume > 0.0;
            }
            (None, Some(_), None) => {
                v.err(
                    format!("{path}.volume"),
                    "a pressure inlet needs the `volume` its reservoir holds (m³; m² in 2D)",
                );
                ok = false;
            }
            (Some(_), _, Some(_)) => {
                v.err(
                    format!("{path}.volume"),
                    "an inlet at a set `rate` takes its volume from the rate and the time: \
                     remove this (or give `pressure` instead of `rate`)",
                );
                ok = false;
            }
            (Some(_), Some(_), None) => {
                v.err(
                    path,
                    "give the inlet's `rate` or its reservoir's `pressure`, not both",
                );
                ok = false;
            }
            (None, None, _) => {
                v.err(
                    path,
                    "give the inlet's volume flow `rate`, or its reservoir's `pressure` and \
                     `volume`",
                );
                ok = false;
            }
        }
        if !(self.start.is_finite() && self.start >= 0.0) {
            v.err(format!("{path}.start"), "must be a finite time >= 0");
            ok = false;
        }
        let end = self.end_time(s.solver.end_time);
        if !(end.is_finite() && end > self.start) {
            v.err(
                format!("{path}.end"),
                format!(
                    "the flow must end after it starts ({:e} s); it ends at {end:e} s",
                    self.start
                ),
            );
            ok = false;
        }
        if !matches!(s.solver.mechanics, super::Mechanics::Incompressible(_)) {
            v.err(
                path,
                "liquid enters through an inlet only in incompressible mechanics \
                 (solver.mechanics: {\"incompressible\": {}})",
            );
        }
        if !ok || s.domain.min.len() != dim || s.domain.max.len() != dim {
            return;
        }
        // The inlet face, where the particles wait, at the start and at the end of the
        // flow must lie inside the domain (the path between is a straight line).
        let layout = self.layout(dim, h, s.solver.end_time);
        for (t, when) in [(self.start, "start"), (end, "end")] {
            let c = layout.center_at(t);
            for o in &layout.offsets {
                for a in 0..dim {
                    let x = c[a] + o[a];
                    if x < s.domain.min[a] || x > s.domain.max[a] {
                        v.err(
                            format!("{path}.center"),
                            format!(
                                "at its {when} ({t:e} s) the inlet reaches {x:e} on axis {a}, \
                                 outside the domain [{:e}, {:e}]",
                                s.domain.min[a], s.domain.max[a]
                            ),
                        );
                        return;
                    }
                }
            }
        }
    }

    /// The waiting places of every particle, layer by layer (layer-major, in the order the
    /// runtime numbers them), for a scene ending at `end_time`.
    pub(super) fn positions(&self, dim: usize, h: f64, end_time: f64) -> Vec<f64> {
        let layout = self.layout(dim, h, end_time);
        let mut out = Vec::with_capacity(layout.particles() * dim);
        for layer in 0..layout.layers {
            let c = layout.center_at(layout.entry_time(layer));
            for o in &layout.offsets {
                out.extend((0..dim).map(|a| c[a] + o[a]));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inflow(width: Option<f64>, radius: Option<f64>) -> Inflow {
        Inflow {
            center: vec![0.0, 0.0, 0.0],
            direction: vec![0.0, 0.0, -2.0],
            width,
            radius,
            rate: Some(1e-6),
            pressure: None,
            volume: None,
            start: 0.5,
            end: Some(1.5),
            velocity: Some(vec![0.01, 0.0, 0.0]),
        }
    }

    #[test]
    fn the_layers_carry_the_rate() {
        let h = 1e-3;
        for shape in [inflow(Some(4e-3), None), inflow(None, Some(2e-3))] {
            let layout = shape.layout(3, h, 10.0);
            let volume = layout.particles() as f64 * h.powi(3);
            // One second at 1e-6 m³/s, to within half a layer.
            let half_layer = 0.5 * layout.offsets.len() as f64 * h.powi(3);
            assert!((volume - 1e-6).abs() <= half_layer + 1e-18, "{volume}");
            assert_eq!(layout.direction, [0.0, 0.0, -1.0]);
            let t0 = layout.entry_time(0);
            assert!((t0 - (0.5 + 0.5 * h / layout.speed)).abs() < 1e-15);
            let c = layout.center_at(1.5);
            assert!((c[0] - 0.01).abs() < 1e-15);
            let estimate = shape.particle_estimate(3, h, 10.0);
            let made = layout.particles() as f64;
            assert!((estimate - made).abs() <= 0.3 * made, "{estimate} {made}");
        }
        // At a set pressure the reservoir's volume makes the layers, whatever the time.
        let mut pressure = inflow(Some(4e-3), None);
        pressure.rate = None;
        pressure.pressure = Some(100.0);
        pressure.volume = Some(3.2e-7);
        let layout = pressure.layout(3, h, 10.0);
        assert_eq!(layout.particles(), 320);
        assert_eq!(layout.pressure, Some(100.0));
        assert_eq!(layout.entry_time(7), 0.5);
        assert_eq!(layout.end, 1.5);
        assert_eq!(layout.half_width, 2e-3);
        let estimate = pressure.particle_estimate(3, h, 10.0);
        assert!((estimate - 320.0).abs() < 1e-9, "{estimate}");
        let c = layout.center_at(0.5);
        assert!(layout.reaches(&c, &[c[0] + 2.4e-3, c[1], c[2] - 0.5e-3], 0.0, 1e-3, 1e-3));
        assert!(!layout.reaches(&c, &[c[0] + 2.6e-3, c[1], c[2] - 0.5e-3], 0.0, 1e-3, 1e-3));
        assert!(!layout.reaches(&c, &[c[0], c[1], c[2] + 0.5e-3], 0.0, 1e-3, 1e-3));
        let round = inflow(None, Some(2e-3)).layout(3, h, 10.0);
        assert_eq!(round.offsets.len(), 12); // the 4 x 4 square less its corners
        for o in &round.offsets {
            assert!(o[2].abs() < 1e-15, "across the face: {o:?}");
        }
    }
}
