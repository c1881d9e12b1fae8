//! The `physics.underfill` scene section and its checks.

use crate::viscosity::Viscosity;
use mpm_core::scene::{Issue, Scene, Side};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Scene section `physics.underfill`: liquid drawn into a thin gap by capillary pressure.
///
/// The bodies of the named materials are the gap (its open space); the liquid's volume
/// fraction lives on the grid cells they cover and moves by the flow solved there each step.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UnderfillParameters {
    /// How the flow across the gap is treated.
    pub mode: FlowMode,
    /// Materials whose bodies make up the gap (default: every material a body uses).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<String>,
    /// The liquid: its contact angle, and density, viscosity and surface tension unless the
    /// gap's material is a `liquid` that has them.
    pub fluid: FluidSection,
    /// Gap height h between die and substrate, m. Gap-averaged mode: the plate spacing.
    /// Cross-section mode: measured from the geometry across `gap_axis` instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap: Option<f64>,
    /// Cross-section mode: the axis across the gap (the plates are normal to it).
    #[serde(default = "default_gap_axis")]
    pub gap_axis: usize,
    /// Gap-averaged mode: a regular array of solder bumps that block the gap.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bumps: Option<BumpArray>,
    /// Domain faces where the gap meets liquid at a given pressure (the dispensed bead, or
    /// an inlet and outlet for a pressure-driven test).
    pub reservoirs: Vec<Reservoir>,
    /// Domain faces open to the air (the die edges without underfill). Air that loses its
    /// path to every vent is a void. Default: every face that is not a reservoir.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vents: Option<Vec<Side>>,
    /// Cross-section mode: boxes of the section where the air leaves across its plane, as
    /// beside a solder bump, where the real gap opens around the joint. Open cells whose
    /// centres lie inside are vents; a bump in a section closes the gap, and without such
    /// a box all air between it and the front would be trapped.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub vent_regions: Vec<VentRegion>,
    /// Liquid present at t = 0.
    #[serde(default)]
    pub initial_fill: InitialFill,
    /// The air.
    #[serde(default)]
    pub air: Air,
    /// Gap-averaged mode: relative residual at which the pressure solve stops.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Gap-averaged mode: most conjugate-gradient iterations per step; more stops the run.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: u32,
    /// Temperature of the liquid where no thermal physics gives one, K (for
    /// temperature-dependent viscosity).
    #[serde(default = "default_temperature")]
    pub temperature: f64,
}

fn default_gap_axis() -> usize {
    1
}
fn default_tolerance() -> f64 {
    1e-9
}
fn default_max_iterations() -> u32 {
    20_000
}
fn default_temperature() -> f64 {
    298.15
}

/// Treatment of the flow across the gap.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FlowMode {
    /// Depth-averaged over the gap (Hele-Shaw lubrication): the scene is the die plane, the
    /// mean velocity is −(h²/12μ)·∇p, capillary pressure 2σcosθ/h acts at the front. For a
    /// whole die with its bump array.
    GapAveraged,
    /// The gap resolved in a 2D cross-section: incompressible Stokes flow (with inertia)
    /// between no-slip walls, capillary pressure jump at the free surface. Checks the first.
    CrossSection,
}

/// Scene section `physics.underfill.fluid`: the contact angle, and the liquid's own
/// properties where the gap's material does not give them (a flow-only scene makes the
/// gap's material the `liquid` itself and names each property once).
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FluidSection {
    /// Density, kg/m³ (inertia of the cross-section mode); default: the gap's liquid's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// Viscosity law; default: the gap's liquid's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viscosity: Option<Viscosity>,
    /// Surface tension σ, N/m; default: the gap's liquid's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_tension: Option<f64>,
    /// Static contact angle θ on die and substrate, degrees (below 90: the gap wets).
    pub contact_angle: f64,
}

/// The liquid's properties, resolved from `physics.underfill.fluid` and the gap's `liquid`
/// material.
#[derive(Clone, Debug)]
pub struct Fluid {
    /// Density, kg/m³ (inertia of the cross-section mode).
    pub density: f64,
    /// Viscosity law.
    pub viscosity: Viscosity,
    /// Surface tension σ, N/m.
    pub surface_tension: f64,
    /// Static contact angle θ on die and substrate, degrees (below 90: the gap wets).
    pub contact_angle: f64,
}

impl Fluid {
    /// σ·cosθ, N/m.
    pub fn wetting_tension(&self) -> f64 {
        self.surface_tension * self.contact_angle.to_radians().cos()
    }

    /// Every problem with the resolved properties, with JSON paths below `fp` (the
    /// section's, `physics.underfill.fluid`).
    fn check(&self, fp: &str) -> Vec<Issue> {
        let mut issues = Vec::new();
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.density) {
            issues.push(Issue::new(
                format!("{fp}.density"),
                format!("must be a finite number > 0 (got {})", self.density),
            ));
        }
        if !positive(self.surface_tension) {
            issues.push(Issue::new(
                format!("{fp}.surface_tension"),
                format!(
                    "must be a finite number > 0 N/m (got {})",
                    self.surface_tension
                ),
            ));
        }
        if !(self.contact_angle.is_finite() && (0.0..90.0).contains(&self.contact_angle)) {
            issues.push(Issue::new(
                format!("{fp}.contact_angle"),
                format!(
                    "must lie in [0, 90) degrees: a liquid that does not wet the gap is not drawn in (got {})",
                    self.contact_angle
                ),
            ));
        }
        issues.extend(self.viscosity.check(&format!("{fp}.viscosity")));
        issues
    }
}

/// Most bumps an array may have (flip-chip-underfill has 1,296).
const MAX_BUMPS: f64 = 1e6;

/// A square or staggered array of round bumps (solder joints) spanning the gap.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BumpArray {
    /// Bump diameter, m.
    pub diameter: f64,
    /// Centre-to-centre spacing along both axes, m.
    pub pitch: f64,
    /// Layout.
    #[serde(default)]
    pub pattern: BumpPattern,
    /// Lower corner of the array region, m (the first bump sits half a pitch inside it).
    pub min: [f64; 2],
    /// Upper corner of the array region, m.
    pub max: [f64; 2],
    /// Add the wetted bump walls to the capillary pressure inside the array:
    /// σcosθ·(2/h + πD/(P² − πD²/4)) (the wetted perimeter per open area of a unit cell).
    #[serde(default = "default_true")]
    pub wetting: bool,
}

fn default_true() -> bool {
    true
}

/// Bump layout.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BumpPattern {
    /// Rows and columns at the pitch.
    #[default]
    Square,
    /// Every other row shifted by half a pitch.
    Staggered,
}

impl BumpArray {
    /// Centres of the bumps.
    pub fn centres(&self) -> Vec<[f64; 2]> {
        let mut out = Vec::new();
        let mut row = 0usize;
        let mut y = self.min[1] + 0.5 * self.pitch;
        while y <= self.max[1] - 0.5 * self.pitch + 1e-12 * self.pitch {
            let shift = match self.pattern {
                BumpPattern::Staggered if row % 2 == 1 => 0.5 * self.pitch,
                _ => 0.0,
            };
            let mut x = self.min[0] + 0.5 * self.pitch + shift;
            while x <= self.max[0] - 0.5 * self.pitch + 1e-12 * self.pitch {
                out.push([x, y]);
                x += self.pitch;
            }
            y += self.pitch;
            row += 1;
        }
        out
    }

    /// Wetted bump perimeter per unit open area of the array's unit cell, 1/m.
    pub fn wetted_perimeter_per_area(&self) -> f64 {
        let d = self.diameter;
        std::f64::consts::PI * d / (self.pitch * self.pitch - std::f64::consts::PI * d * d / 4.0)
    }
}

/// Liquid at a domain face.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Reservoir {
    /// Faces it covers.
    pub sides: Vec<Side>,
    /// Gauge pressure of the liquid there, Pa (0: a dispensed bead at ambient pressure).
    #[serde(default)]
    pub pressure: f64,
    /// Only the part of the faces between these coordinates along the face's first free
    /// axis (an edge segment), m; default: the whole face.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub span: Option<[f64; 2]>,
}

/// A box of a cross-section where the air escapes across the section's plane.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VentRegion {
    /// Lower corner, m.
    pub min: [f64; 2],
    /// Upper corner, m.
    pub max: [f64; 2],
}

impl VentRegion {
    /// Whether point `x` lies inside.
    pub fn contains(&self, x: [f64; 2]) -> bool {
        (0..2).all(|a| x[a] >= self.min[a] && x[a] <= self.max[a])
    }
}

/// Liquid present at t = 0.
#[derive(Clone, Debug, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum InitialFill {
    /// The gap is empty.
    #[default]
    Empty,
    /// The gap is full (flow tests).
    Full,
    /// Cells whose centre lies in this box are full.
    Box {
        /// Lower corner, m.
        min: [f64; 2],
        /// Upper corner, m.
        max: [f64; 2],
    },
}

/// The air in the gap.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Air {
    /// Ambient (absolute) pressure, Pa.
    #[serde(default = "default_ambient")]
    pub ambient_pressure: f64,
    /// Trapped air keeps its volume from the moment it is enclosed (an ideal gas at
    /// capillary pressures of kPa against an ambient ~100 kPa yields ~1% of it); off:
    /// enclosed air offers no resistance and the liquid fills it.
    #[serde(default = "default_true")]
    pub trapped_gas: bool,
    /// Enclosed air below this area when it closes is not a void (it is below what the
    /// grid resolves), m²; default: two cells.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_void_area: Option<f64>,
}

fn default_ambient() -> f64 {
    101_325.0
}

impl Default for Air {
    fn default() -> Self {
        Self {
            ambient_pressure: default_ambient(),
            trapped_gas: true,
            min_void_area: None,
        }
    }
}

impl UnderfillParameters {
    /// The liquid's properties: each one the `fluid` section gives, else the gap's
    /// `liquid` material's (the first gap material of type `liquid`); an issue at
    /// `fp.<property>` for each that neither gives.
    pub fn resolved_fluid(&self, scene: &Scene, fp: &str) -> Result<Fluid, Vec<Issue>> {
        let gap_materials: Vec<&String> = if self.materials.is_empty() {
            scene.bodies.iter().map(|b| &b.material).collect()
        } else {
            self.materials.iter().collect()
        };
        let liquid = gap_materials.iter().find_map(|name| {
            let mut value = scene.materials.get(name.as_str())?.clone();
            let object = value.as_object_mut()?;
            if object.remove("type")?.as_str()? != "liquid" {
                return None;
            }
            serde_json::from_value::<crate::liquid::LiquidParameters>(value).ok()
        });
        let section = &self.fluid;
        let mut issues = Vec::new();
        let mut missing = |field: &str| {
            issues.push(Issue::new(
                format!("{fp}.{field}"),
                "give it here, or make the gap's material a `liquid` that has it",
            ))
        };
        let density = section.density.or(liquid.as_ref().map(|l| l.density));
        let viscosity = section
            .viscosity
            .clone()
            .or(liquid.as_ref().map(|l| l.viscosity.clone()));
        let surface_tension = section
            .surface_tension
            .or(liquid.as_ref().map(|l| l.surface_tension));
        if density.is_none() {
            missing("density");
        }
        if viscosity.is_none() {
            missing("viscosity");
        }
        if surface_tension.is_none() {
            missing("surface_tension");
        }
        match (density, viscosity, surface_tension) {
            (Some(density), Some(viscosity), Some(surface_tension)) => Ok(Fluid {
                density,
                viscosity,
                surface_tension,
                contact_angle: section.contact_angle,
            }),
            _ => Err(issues),
        }
    }

    /// Every problem with the section, with JSON paths below `path`.
    pub fn check(&self, path: &str, scene: &Scene) -> Vec<Issue> {
        let mut issues = Vec::new();
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if scene.dimension != 2 {
            issues.push(Issue::new(
                format!("{path}.mode"),
                "underfill flow runs on 2D scenes: the die plane (gap_averaged) or a cross-section of the gap (cross_section)",
            ));
        }
        if scene.solver.mechanics != mpm_core::scene::Mechanics::Off {
            issues.push(Issue::new(
                "solver.mechanics",
                "underfill flow needs `\"mechanics\": \"off\"`: the particles are the gap's geometry, the liquid moves on the grid",
            ));
        }
        for (i, m) in self.materials.iter().enumerate() {
            if !scene.materials.contains_key(m) {
                issues.push(Issue::new(
                    format!("{path}.materials[{i}]"),
                    format!("no material `{m}` in the scene's `materials`"),
                ));
            }
        }
        let fp = format!("{path}.fluid");
        match self.resolved_fluid(scene, &fp) {
            Ok(f) => issues.extend(f.check(&fp)),
            Err(missing) => issues.extend(missing),
        }
        match self.mode {
            FlowMode::GapAveraged => match self.gap {
                Some(h) if positive(h) => {}
                Some(h) => issues.push(Issue::new(
                    format!("{path}.gap"),
                    format!("must be a finite number > 0 m (got {h})"),
                )),
                None => issues.push(Issue::new(
                    format!("{path}.gap"),
                    "the gap_averaged mode needs the gap height, m",
                )),
            },
            FlowMode::CrossSection => {
                if self.gap_axis > 1 {
                    issues.push(Issue::new(
                        format!("{path}.gap_axis"),
                        "must be 0 or 1 in a 2D cross-section",
                    ));
                }
                if self.bumps.is_some() {
                    issues.push(Issue::new(
                        format!("{path}.bumps"),
                        "bump arrays belong to the gap_averaged mode; in a cross-section draw bumps as holes in the body",
                    ));
                }
                if let Some(h) = self.gap
                    && !positive(h)
                {
                    issues.push(Issue::new(
                        format!("{path}.gap"),
                        format!("must be a finite number > 0 m (got {h})"),
                    ));
                }
            }
        }
        if let Some(b) = &self.bumps {
            let bp = format!("{path}.bumps");
            if !positive(b.diameter) {
                issues.push(Issue::new(
                    format!("{bp}.diameter"),
                    format!("must be a finite number > 0 m (got {})", b.diameter),
                ));
            }
            if !(positive(b.pitch) && b.pitch > b.diameter) {
                issues.push(Issue::new(
                    format!("{bp}.pitch"),
                    format!(
                        "must be finite and larger than the diameter, or the bumps would close the gap (got {})",
                        b.pitch
                    ),
                ));
            }
            for a in 0..2 {
                if !(b.min[a].is_finite() && b.max[a].is_finite() && b.max[a] > b.min[a]) {
                    issues.push(Issue::new(
                        format!("{bp}.max[{a}]"),
                        "the array region needs max > min along each axis",
                    ));
                }
            }
            // The bumps are listed before they are cut out of the cells: bound their count.
            let count: f64 = (0..2).map(|a| (b.max[a] - b.min[a]) / b.pitch).product();
            if count > MAX_BUMPS {
                issues.push(Issue::new(
                    format!("{bp}.pitch"),
                    format!(
                        "the array region would hold about {count:.3e} bumps at this pitch; at \
                         most {MAX_BUMPS:e} are allowed"
                    ),
                ));
            }
        }
        if self.reservoirs.is_empty() {
            issues.push(Issue::new(
                format!("{path}.reservoirs"),
                "name at least one face where liquid enters",
            ));
        }
        let dim = scene.dimension as usize;
        let check_side = |issues: &mut Vec<Issue>, side: &Side, p: String| {
            if side.axis_and_upper().0 >= dim {
                issues.push(Issue::new(p, format!("a {dim}D domain has no such face")));
            }
        };
        for (i, r) in self.reservoirs.iter().enumerate() {
            let rp = format!("{path}.reservoirs[{i}]");
            if r.sides.is_empty() {
                issues.push(Issue::new(format!("{rp}.sides"), "name at least one face"));
            }
            for (k, s) in r.sides.iter().enumerate() {
                check_side(&mut issues, s, format!("{rp}.sides[{k}]"));
            }
            if !r.pressure.is_finite() {
                issues.push(Issue::new(format!("{rp}.pressure"), "must be finite"));
            }
            if let Some([a, b]) = r.span
                && !(a.is_finite() && b.is_finite() && b > a)
            {
                issues.push(Issue::new(
                    format!("{rp}.span"),
                    "must be [from, to] with to > from",
                ));
            }
        }
        if let Some(vents) = &self.vents {
            for (k, s) in vents.iter().enumerate() {
                check_side(&mut issues, s, format!("{path}.vents[{k}]"));
                if self.reservoirs.iter().any(|r| r.sides.contains(s)) {
                    issues.push(Issue::new(
                        format!("{path}.vents[{k}]"),
                        "a face cannot be both a reservoir and a vent",
                    ));
                }
            }
        }
        for (k, r) in self.vent_regions.iter().enumerate() {
            let rp = format!("{path}.vent_regions[{k}]");
            if self.mode != FlowMode::CrossSection {
                issues.push(Issue::new(
                    rp.clone(),
                    "vent regions are for the cross_section mode (a gap-averaged gap vents at its faces)",
                ));
            }
            for a in 0..2 {
                if !(r.min[a].is_finite() && r.max[a].is_finite() && r.max[a] > r.min[a]) {
                    issues.push(Issue::new(
                        format!("{rp}.max[{a}]"),
                        "needs max > min along each axis",
                    ));
                }
            }
        }
        if let InitialFill::Box { min, max } = &self.initial_fill {
            for a in 0..2 {
                if !(min[a].is_finite() && max[a].is_finite() && max[a] > min[a]) {
                    issues.push(Issue::new(
                        format!("{path}.initial_fill.box.max[{a}]"),
                        "needs max > min along each axis",
                    ));
                }
            }
        }
        if !positive(self.air.ambient_pressure) {
            issues.push(Issue::new(
                format!("{path}.air.ambient_pressure"),
                format!(
                    "must be a finite absolute pressure > 0 Pa (got {})",
                    self.air.ambient_pressure
                ),
            ));
        }
        if let Some(a) = self.air.min_void_area
            && !(a.is_finite() && a >= 0.0)
        {
            issues.push(Issue::new(
                format!("{path}.air.min_void_area"),
                format!("must be a finite area >= 0 m² (got {a})"),
            ));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            issues.push(Issue::new(
                format!("{path}.tolerance"),
                format!("must lie in (0, 1) (got {})", self.tolerance),
            ));
        }
        if self.max_iterations == 0 {
            issues.push(Issue::new(
                format!("{path}.max_iterations"),
                "must be at least 1",
            ));
        }
        if !positive(self.temperature) {
            issues.push(Issue::new(
                format!("{path}.temperature"),
                format!("must be a finite number > 0 K (got {})", self.temperature),
            ));
        }
        issues
    }
}
