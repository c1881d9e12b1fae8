//! References for liquid particles (`liquid` material, incompressible mechanics): the
//! hydrostatic tank and the dam break of Martin & Moyce (1952).

use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Liquid at rest in a tank: the particles' `pressure` against ρ·g·(surface − x_axis).
/// Error: relative L2 error of the pressure over the particles at the last frame.
/// Comparisons: `bottom_pressure` (the deepest particle's pressure against ρgh) and
/// `spurious_speed` (the largest particle speed, against the gravity-wave speed √(g·depth)
/// of the tank: its relative difference + 1 is the spurious speed in that unit).
#[derive(Clone, Copy, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct HydrostaticParams {
    /// Vertical axis (gravity points along −axis).
    pub axis: usize,
    /// Coordinate of the free surface along the axis, m.
    pub surface: f64,
    /// Coordinate of the tank's floor along the axis, m.
    pub floor: f64,
    /// Liquid density, kg/m³.
    pub density: f64,
    /// Magnitude of gravity, m/s².
    pub gravity: f64,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Hydrostatic {
    p: HydrostaticParams,
    error: Option<f64>,
    comparisons: Vec<Comparison>,
}

/// The `pressure` values of every liquid particle, with their storage indices (the
/// liquid references of this plugin read them through this one place).
pub(crate) fn pressures<'a, const D: usize>(
    particles: &'a mpm_core::particles::Particles<D>,
) -> impl Iterator<Item = (usize, f64)> + 'a {
    particles.groups.iter().flat_map(|g| {
        let field = g
            .material
            .state_fields()
            .iter()
            .position(|f| f.name == "pressure");
        g.range
            .clone()
            .enumerate()
            .filter_map(move |(k, i)| field.map(|f| (i, g.state[f][k])))
    })
}

impl ReferenceLaw for Hydrostatic {
    fn kind(&self) -> &'static str {
        "relative L2 error of the particle pressure against rho g h (hydrostatic tank), last frame"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if frame.time <= 0.0 {
            return;
        }
        let p = self.p;
        let particles = frame.particles;
        let mut l2 = RelativeL2::default();
        let (mut deepest, mut deepest_at) = (f64::INFINITY, None);
        for (i, pressure) in pressures(particles) {
            let x = particles.position[i][p.axis];
            let exact = p.density * p.gravity * (p.surface - x);
            l2.add((pressure - exact).powi(2), exact * exact);
            if x < deepest {
                deepest = x;
                deepest_at = Some((pressure, exact));
            }
        }
        let speed = particles
            .velocity
            .iter()
            .map(|v| v.norm())
            .fold(0.0, f64::max);
        self.error = l2.value();
        self.comparisons.clear();
        if let Some((measured, exact)) = deepest_at {
            self.comparisons
                .push(compare("bottom_pressure", measured, exact));
        }
        let wave = (p.gravity * (p.surface - p.floor)).sqrt();
        self.comparisons
            .push(compare("spurious_speed", speed, wave));
    }

    fn error(&self) -> Option<f64> {
        self.error
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

fn build_hydrostatic(
    p: HydrostaticParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    c.finite("floor", p.floor);
    c.finite("surface", p.surface);
    c.positive("density", p.density);
    c.positive("gravity", p.gravity);
    if p.surface <= p.floor {
        c.error("surface", "must lie above `floor`");
    }
    c.finish()?;
    Ok(Arc::new(Hydrostatic {
        p,
        error: None,
        comparisons: Vec::new(),
    }))
}

/// Surge front of the collapse of a liquid column of width a and height 2a (n² = 2) on a
/// dry floor, Martin & Moyce (1952), Phil. Trans. R. Soc. A 244, 312–324, Table 2 (a = 2¼
/// in): dimensionless time T = t·√(2g/a) and front Z = z/a, as the table is commonly
/// reproduced in free-surface solver validations.
pub const MARTIN_MOYCE_N2: [(f64, f64); 15] = [
    (0.41, 1.11),
    (0.84, 1.22),
    (1.19, 1.44),
    (1.43, 1.67),
    (1.63, 1.89),
    (1.83, 2.11),
    (1.98, 2.33),
    (2.20, 2.56),
    (2.32, 2.78),
    (2.51, 3.00),
    (2.65, 3.22),
    (2.83, 3.44),
    (2.98, 3.67),
    (3.11, 3.89),
    (3.33, 4.11),
];

/// The Martin & Moyce front Z at dimensionless time `t`, linear between the table's
/// points; `None` outside them.
pub fn martin_moyce_front(t: f64) -> Option<f64> {
    let table = &MARTIN_MOYCE_N2;
    if t < table[0].0 || t > table[table.len() - 1].0 {
        return None;
    }
    table.windows(2).find_map(|w| {
        let ((t0, z0), (t1, z1)) = (w[0], w[1]);
        (t >= t0 && t <= t1).then(|| z0 + (z1 - z0) * (t - t0) / (t1 - t0))
    })
}

/// Dam break (a column of width a and height 2a collapsing on a dry floor, walls at the
/// back and below): the surge front against Martin & Moyce (1952). The measured front is
/// the largest particle coordinate along `axis`, less `wall`, over a; error: relative L2
/// error of Z over the output frames whose T lies within the data (0.41 ≤ T ≤ 3.33).
#[derive(Clone, Copy, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct DamBreakParams {
    /// Axis the front runs along.
    pub axis: usize,
    /// Coordinate of the wall behind the column along the axis, m.
    pub wall: f64,
    /// Initial column width a, m (its height is 2a).
    pub width: f64,
    /// Magnitude of gravity, m/s².
    pub gravity: f64,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct DamBreak {
    p: DamBreakParams,
    error: RelativeL2,
    measured: Option<f64>,
    expected: Option<f64>,
    comparisons: Vec<Comparison>,
}

impl ReferenceLaw for DamBreak {
    fn kind(&self) -> &'static str {
        "relative L2 error of the surge front z/a against Martin & Moyce (1952), n^2 = 2, over frames with 0.41 <= t sqrt(2g/a) <= 3.33"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let p = self.p;
        let front = frame
            .particles
            .position
            .iter()
            .map(|x| x[p.axis])
            .fold(f64::NEG_INFINITY, f64::max);
        let z = (front - p.wall) / p.width;
        let t = frame.time * (2.0 * p.gravity / p.width).sqrt();
        if let Some(exact) = martin_moyce_front(t) {
            self.error.add((z - exact).powi(2), exact * exact);
            self.measured = Some(z);
            self.expected = Some(exact);
            self.comparisons.clear();
            self.comparisons.push(compare("front_z_over_a", z, exact));
        }
    }

    fn error(&self) -> Option<f64> {
        self.error.value()
    }

    fn expected(&self) -> Option<f64> {
        self.expected
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

fn build_dam_break(
    p: DamBreakParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    c.finite("wall", p.wall);
    c.positive("width", p.width);
    c.positive("gravity", p.gravity);
    c.finish()?;
    Ok(Arc::new(DamBreak {
        p,
        error: RelativeL2::default(),
        measured: None,
        expected: None,
        comparisons: Vec::new(),
    }))
}

/// The `hydrostatic` and `dam_break` reference types.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![
        Box::new(TypedReferenceFactory::new("hydrostatic", build_hydrostatic)),
        Box::new(TypedReferenceFactory::new("dam_break", build_dam_break)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn martin_moyce_front_interpolates_the_table() {
        assert_eq!(martin_moyce_front(0.2), None);
        assert!((martin_moyce_front(0.41).unwrap() - 1.11).abs() < 1e-12);
        assert!((martin_moyce_front(2.51).unwrap() - 3.0).abs() < 1e-12);
        let mid = martin_moyce_front(0.5 * (2.51 + 2.65)).unwrap();
        assert!((mid - 3.11).abs() < 1e-12);
        assert_eq!(martin_moyce_front(3.4), None);
    }
}
