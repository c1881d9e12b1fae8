//! Reference for capillary rise (`obstacles[].contact_angle` under gravity): two parallel
//! plates dipping into a pool draw the liquid up between them to Jurin's height
//! h = 2σ·cos θ/(ρ·g·w) above the pool's level (plates w apart). The balance is of forces
//! on the whole column (the wetting pull 2σ·cos θ per unit depth against the weight of the
//! liquid above the pool), so it holds for the column's mean height, whatever the shape of
//! the meniscus, and is what this reference measures.
//!
//! Beside it, `surface_rise`: the column's free surface over the pool's, each the mean of
//! the highest particle in strips one particle spacing wide. The volume measure counts
//! particles, so where they crowd (at the contact lines, without a volume source) it reads
//! a column higher than its surface stands; the two differ by that crowding.
//!
//! The pool's volume counts a particle near a stretch's end inside the domain by the share
//! of its width (one particle spacing) inside the stretch. Counted whole by its centre, a
//! stretch 2 mm wide gained or lost a whole column of particles (an eighth of its count)
//! when the pool's lattice sheared, and the pool read 0.2 mm low (stop 83).

use crate::meniscus_reference::{check_angle, check_plates};
use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Liquid between plates at `plates[0]` and `plates[1]` along `across` (the inner faces),
/// gravity along −`up`, with the pool's level measured over the stretches `pool` along
/// `across`, away from the plates. Heights are liquid volume over footprint (the particles'
/// volumes summed in each stretch, over its width times the domain's extent along the other
/// axes), so the pool and the column must stand on the same flat floor; a stretch's end
/// inside the domain counts the particles across it by their share inside. Error: relative
/// error of the rise (column height − pool height) against Jurin's 2σ·cos θ/(ρ·g·w), at
/// the last frame. Comparisons: `jurin_rise` (that rise) and `surface_rise` (the mean height
/// of the column's free surface above the pool's, both from the highest particle in each
/// strip one particle spacing wide; empty strips are left out).
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct CapillaryRiseParams {
    /// Positions of the plates' inner faces along `across`, m (lower first).
    pub plates: [f64; 2],
    /// Stretches `[from, to]` along `across`, m, over which the pool's level is measured.
    pub pool: Vec<[f64; 2]>,
    /// Axis normal to the plates (default 0).
    #[serde(default)]
    pub across: usize,
    /// Axis against gravity (default 1).
    #[serde(default = "default_up")]
    pub up: usize,
    /// Surface tension σ, N/m.
    pub surface_tension: f64,
    /// Static contact angle θ on the plates, degrees, through the liquid.
    pub contact_angle: f64,
    /// Density ρ of the liquid, kg/m³.
    pub density: f64,
}

fn default_up() -> usize {
    1
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct CapillaryRise {
    p: CapillaryRiseParams,
    /// Gravity's magnitude along −`up`, m/s².
    gravity: f64,
    /// The domain's extent along the axes other than `across` and `up` (1 in 2D), m.
    depth: f64,
    /// Width of the strips the free surface is found in: the widest particle spacing of
    /// the scene's bodies, m.
    strip: f64,
    /// The axis other than `across` and `up` (3D), its domain minimum and strip count.
    depth_axis: Option<(usize, f64, usize)>,
    /// The domain's bounds along `across`: a pool stretch's end there counts sharply, one
    /// inside ramps over a particle spacing. Absent from checkpoints written before the
    /// ramp (stop 84), which count every end sharply as they did.
    #[serde(default)]
    bounds: Option<[f64; 2]>,
    error: Option<f64>,
    comparisons: Vec<Comparison>,
}

impl CapillaryRise {
    /// Jurin's height 2σ·cos θ/(ρ·g·w).
    fn jurin(&self) -> f64 {
        let p = &self.p;
        let w = p.plates[1] - p.plates[0];
        2.0 * p.surface_tension * p.contact_angle.to_radians().cos()
            / (p.density * self.gravity * w)
    }
}

impl CapillaryRise {
    /// The share of a particle centred at `s` (along `across`) that lies in the stretch
    /// `[from, to]`: 0 or 1 by its centre at an end on the domain's bound, else ramped
    /// linearly over one particle spacing centred on the end.
    fn pool_share(&self, s: f64, from: f64, to: f64) -> f64 {
        let ramp = |inside: f64| (inside / self.strip + 0.5).clamp(0.0, 1.0);
        let sharp = |inside: f64| if inside > 0.0 { 1.0 } else { 0.0 };
        let [low, high] = self.bounds.unwrap_or([from, to]);
        let lower = if from > low {
            ramp(s - from)
        } else {
            sharp(s - from)
        };
        let upper = if to < high {
            ramp(to - s)
        } else {
            sharp(to - s)
        };
        lower * upper
    }

    /// Mean over the strips of `[from, to]` along `across` (and along the depth axis in 3D)
    /// of the highest particle's position along `up`; `None` without particles there.
    fn surface<const D: usize>(
        &self,
        positions: &[mpm_core::math::Vector<D>],
        from: f64,
        to: f64,
    ) -> Option<(f64, usize)> {
        let p = &self.p;
        let across = ((to - from) / self.strip).ceil().max(1.0) as usize;
        let deep = self.depth_axis.map_or(1, |(_, _, n)| n);
        let mut top = vec![f64::NEG_INFINITY; across * deep];
        for x in positions {
            let s = x[p.across];
            if !(s > from && s < to) {
                continue;
            }
            let i = (((s - from) / self.strip) as usize).min(across - 1);
            let k = self.depth_axis.map_or(0, |(axis, min, n)| {
                (((x[axis] - min) / self.strip).max(0.0) as usize).min(n - 1)
            });
            let t = &mut top[k * across + i];
            *t = t.max(x[p.up]);
        }
        let (sum, count) = top
            .iter()
            .filter(|t| t.is_finite())
            .fold((0.0, 0), |(s, n), t| (s + t, n + 1));
        (count > 0).then_some((sum, count))
    }
}

impl ReferenceLaw for CapillaryRise {
    fn kind(&self) -> &'static str {
        "relative error of the mean rise of the liquid between plates against Jurin's height, last frame"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let p = &self.p;
        let particles = frame.particles;
        let (mut column, mut pool) = (0.0, 0.0);
        for (x, volume) in particles.position.iter().zip(&particles.volume0) {
            let s = x[p.across];
            if s > p.plates[0] && s < p.plates[1] {
                column += volume;
            }
            pool += volume
                * p.pool
                    .iter()
                    .map(|[from, to]| self.pool_share(s, *from, *to))
                    .sum::<f64>();
        }
        let width: f64 = p.pool.iter().map(|[from, to]| to - from).sum();
        let column = column / ((p.plates[1] - p.plates[0]) * self.depth);
        let pool = pool / (width * self.depth);
        let exact = self.jurin();
        self.error = Some(((column - pool) - exact).abs() / exact.abs());
        self.comparisons = vec![compare("jurin_rise", column - pool, exact)];
        let positions = &particles.position;
        let gap = self.surface(positions, p.plates[0], p.plates[1]);
        let level = p
            .pool
            .iter()
            .filter_map(|[from, to]| self.surface(positions, *from, *to))
            .fold(None, |acc: Option<(f64, usize)>, (sum, n)| {
                let (s0, n0) = acc.unwrap_or((0.0, 0));
                Some((s0 + sum, n0 + n))
            });
        if let (Some((g, ng)), Some((l, nl))) = (gap, level) {
            let rise = g / ng as f64 - l / nl as f64;
            self.comparisons.push(compare("surface_rise", rise, exact));
        }
    }

    fn error(&self) -> Option<f64> {
        self.error
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

fn build_capillary_rise(
    p: CapillaryRiseParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    let dimension = scene.dimension as usize;
    check_plates(&mut c, p.plates, p.across, p.up, dimension);
    if p.pool.is_empty() {
        c.error(
            "pool",
            "must name at least one stretch away from the plates",
        );
    }
    for (i, [from, to]) in p.pool.iter().enumerate() {
        if !(from.is_finite() && to.is_finite() && to > from) {
            c.error(
                &format!("pool[{i}]"),
                "must be two finite positions, the lower first",
            );
        } else if *to > p.plates[0] && *from < p.plates[1] {
            c.error(
                &format!("pool[{i}]"),
                "must lie outside the plates: the pool's level is measured away from them",
            );
        }
    }
    c.positive("surface_tension", p.surface_tension);
    c.positive("density", p.density);
    check_angle(
        &mut c,
        p.contact_angle,
        "the liquid does not rise, and no error relative to 0 exists",
    );
    let gravity = if p.up < dimension {
        -scene
            .solver
            .gravity
            .as_ref()
            .and_then(|g| g.get(p.up).copied())
            .unwrap_or(0.0)
    } else {
        0.0
    };
    if gravity.is_nan() || gravity <= 0.0 {
        c.error(
            "up",
            "gravity (`solver.gravity`) must pull against this axis: Jurin's height needs it",
        );
    }
    c.finish()?;
    let depth = (0..dimension)
        .filter(|&d| d != p.across && d != p.up)
        .map(|d| scene.domain.max[d] - scene.domain.min[d])
        .product();
    let strip = scene
        .bodies
        .iter()
        .map(|b| scene.domain.cell_size / f64::from(b.particles_per_cell.clamp(1, 8)))
        .fold(0.0, f64::max);
    // A scene without bodies (liquid from inlets alone) gets the default spacing.
    let strip = if strip > 0.0 {
        strip
    } else {
        scene.domain.cell_size / 2.0
    };
    let depth_axis = (0..dimension)
        .find(|&d| d != p.across && d != p.up)
        .map(|d| {
            let extent = scene.domain.max[d] - scene.domain.min[d];
            (
                d,
                scene.domain.min[d],
                ((extent / strip).ceil() as usize).max(1),
            )
        });
    let bounds = [scene.domain.min[p.across], scene.domain.max[p.across]];
    Ok(Arc::new(CapillaryRise {
        p,
        gravity,
        depth,
        strip,
        depth_axis,
        bounds: Some(bounds),
        error: None,
        comparisons: Vec::new(),
    }))
}

/// The `capillary_rise` reference type.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![Box::new(TypedReferenceFactory::new(
        "capillary_rise",
        build_capillary_rise,
    ))]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reference whose strips are 0.25 mm wide in a domain 0–37 mm along `across`.
    fn reference() -> CapillaryRise {
        CapillaryRise {
            p: CapillaryRiseParams {
                plates: [0.017, 0.02],
                pool: vec![[0.0, 0.002], [0.035, 0.037]],
                across: 0,
                up: 1,
                surface_tension: 0.07,
                contact_angle: 30.0,
                density: 1000.0,
            },
            gravity: 9.81,
            depth: 1.0,
            strip: 2.5e-4,
            depth_axis: None,
            bounds: Some([0.0, 0.037]),
            error: None,
            comparisons: Vec::new(),
        }
    }

    #[test]
    fn a_stretch_counts_a_shifted_lattice_by_its_width() {
        // Columns of particles one strip apart, shifted by any fraction of a strip: the
        // stretch [1 mm, 2 mm] inside the domain is 4 strips wide. Counted whole by their
        // centres it held 3 columns where two sat on its ends and 4 otherwise; a sheared
        // lattice has no single spacing, and it jumped by whole columns. By shares, 4 to
        // round-off at every shift.
        let r = reference();
        for k in 0..10 {
            let shift = f64::from(k) * 0.1 * r.strip;
            let count: f64 = (0..200)
                .map(|i| r.pool_share(shift + f64::from(i) * r.strip, 0.001, 0.002))
                .sum();
            assert!((count - 4.0).abs() < 1e-9, "shift {shift}: {count}");
        }
    }

    #[test]
    fn an_end_on_the_domains_bound_counts_whole() {
        let r = reference();
        assert_eq!(r.pool_share(1e-5, 0.0, 0.002), 1.0);
        assert_eq!(r.pool_share(0.03699, 0.035, 0.037), 1.0);
        assert_eq!(r.pool_share(0.002, 0.0, 0.002), 0.5);
        // A checkpoint from before the ramp counts every end whole.
        let old = CapillaryRise {
            bounds: None,
            ..reference()
        };
        assert_eq!(old.pool_share(0.00199, 0.0, 0.002), 1.0);
        assert_eq!(old.pool_share(0.00201, 0.0, 0.002), 0.0);
    }
}
