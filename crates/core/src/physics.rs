//! Physics operators beyond the stress update (heat conduction, phase change, cure, ...).
//!
//! A plugin adds one through a [`PhysicsFactory`] that reads the scene's `physics.<name>`
//! section. Each operator declares the scalar particle fields it creates ([`SharedFieldSpec`])
//! and the grid scratch arrays it needs; the core allocates those and nothing else, so a
//! scene pays only for the physics it names. Operators talk to each other and to materials
//! through the shared fields by name (`temperature`, `solid_fraction`, `free_strain`, ...).
//!
//! Every step, after the kinematic update and before the stress update, the core rebuilds
//! the particles' stencils ([`Interpolation`]) and calls each operator's [`Stage::Prepare`],
//! then each one's [`Stage::Advance`], then each one's [`Stage::Finish`], in scene order.
//! An operator transfers to the grid, solves there and gathers back inside its own stages,
//! once per step for all particles (dispatch per step, never per particle).

use crate::grid::Grid;
use crate::math::{Matrix, Vector};
use crate::scene::{Issue, Scene};
use std::ops::Range;
use std::sync::Arc;

/// Name of the shared field holding an isotropic stress-free strain (thermal expansion,
/// cure shrinkage, ...): when a physics creates it, every material sees the mechanical
/// deformation gradient `F / (1 + free_strain)` instead of `F`.
pub const FREE_STRAIN: &str = "free_strain";

/// Name of the shared field where materials report the plastic work they dissipated in the
/// last step, J per m³ of reference volume; present only when a physics consumes it.
pub const PLASTIC_WORK: &str = "plastic_work";

/// Name of the shared field where physics operators deposit heat released in a particle
/// during the current step (heat of reaction), J per m³ of reference volume; a thermal
/// physics conducts it from the particle's neighbourhood in the same step.
pub const HEAT_RELEASE: &str = "heat_release";

/// A scalar per-particle field that a physics operator creates for every particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedFieldSpec {
    /// Name, also the output field name.
    pub name: &'static str,
    /// Value before the operator's [`Stage::Initialise`].
    pub initial: f64,
}

/// The shared scalar particle fields of a run, one `Vec` per field, in particle storage
/// order (the core permutes them when it reorders particles).
#[derive(Default)]
pub struct ParticleFields {
    names: Vec<&'static str>,
    values: Vec<Vec<f64>>,
}

impl ParticleFields {
    /// Adds a field of `n` particles (no-op when it exists).
    pub fn add(&mut self, spec: SharedFieldSpec, n: usize) {
        if !self.names.contains(&spec.name) {
            self.names.push(spec.name);
            self.values.push(vec![spec.initial; n]);
        }
    }

    /// Names of the fields, in creation order.
    pub fn names(&self) -> &[&'static str] {
        &self.names
    }

    /// Whether a field exists.
    pub fn contains(&self, name: &str) -> bool {
        self.names.contains(&name)
    }

    /// A field's values.
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        let i = self.names.iter().position(|n| *n == name)?;
        Some(&self.values[i])
    }

    /// A field's values, mutably.
    pub fn get_mut(&mut self, name: &str) -> Option<&mut [f64]> {
        let i = self.names.iter().position(|n| *n == name)?;
        Some(&mut self.values[i])
    }

    /// Several distinct fields at once, mutably (`None` for a missing or repeated name).
    pub fn many_mut<const N: usize>(&mut self, names: [&str; N]) -> [Option<&mut [f64]>; N] {
        let mut out: [Option<&mut [f64]>; N] = std::array::from_fn(|_| None);
        for (name, values) in self.names.iter().zip(self.values.iter_mut()) {
            let mut hits = (0..N).filter(|&k| names[k] == *name);
            if let (Some(k), None) = (hits.next(), hits.next()) {
                out[k] = Some(values.as_mut_slice());
            }
        }
        out
    }

    /// Moves a field's values out (empty when missing); give them back with [`Self::restore`].
    pub(crate) fn take(&mut self, name: &str) -> Vec<f64> {
        self.get_mut_vec(name)
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// Puts back what [`Self::take`] moved out.
    pub(crate) fn restore(&mut self, name: &str, values: Vec<f64>) {
        if let Some(v) = self.get_mut_vec(name) {
            *v = values;
        }
    }

    fn get_mut_vec(&mut self, name: &str) -> Option<&mut Vec<f64>> {
        let i = self.names.iter().position(|n| *n == name)?;
        Some(&mut self.values[i])
    }

    /// All fields, mutably (the core's reordering).
    pub(crate) fn all_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        self.values.iter_mut()
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.values.iter().map(|v| v.capacity() * 8).sum()
    }
}

/// Every particle's stencil at the current positions: `stencil` nodes per particle, with
/// their row, weight and weight gradient (physical units, 1/m). Physics operators use it for
/// their own particle↔grid transfers without knowing the kernel.
///
/// The physics operators' interpolation has compact rows: a row is a node some stencil
/// reaches, numbered in grid order, so an operator's node arrays hold
/// [`Interpolation::row_count`] values instead of one per grid node (a body in a large box
/// pays for its own nodes only) and sums over rows run in the grid's order.
#[derive(Default)]
pub struct Interpolation<const D: usize> {
    /// Nodes per particle.
    pub stencil: usize,
    /// Row of each stencil entry (particle-major): the grid node, or with compact rows the
    /// node's index in `rows`.
    pub node: Vec<u32>,
    /// Weight of each stencil entry.
    pub weight: Vec<f64>,
    /// Gradient of the weight with respect to the particle position, 1/m.
    pub gradient: Vec<Vector<D>>,
    /// Whether `node` holds compact rows.
    pub compact: bool,
    /// With compact rows, the grid node of each row (ascending); empty otherwise.
    pub rows: Vec<u32>,
    /// The numbering's scratch: one bit per grid node, one bit per word of those that
    /// holds any, and the rows before each word.
    pub(crate) marks: Vec<std::sync::atomic::AtomicU64>,
    pub(crate) summary: Vec<std::sync::atomic::AtomicU64>,
    pub(crate) rank: Vec<u32>,
}

impl<const D: usize> Interpolation<D> {
    /// The stencil entries of particle `p`.
    #[inline(always)]
    pub fn entries(&self, p: usize) -> Range<usize> {
        p * self.stencil..(p + 1) * self.stencil
    }

    /// Rows an operator's node arrays need: the reached nodes with compact rows, else
    /// `grid_nodes` (the grid's length).
    pub fn row_count(&self, grid_nodes: usize) -> usize {
        if self.compact {
            self.rows.len()
        } else {
            grid_nodes
        }
    }

    /// The grid node of `row`.
    #[inline]
    pub fn grid_node(&self, row: usize) -> usize {
        if self.compact {
            self.rows[row] as usize
        } else {
            row
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.node.capacity() * 4
            + self.weight.capacity() * 8
            + self.gradient.capacity() * std::mem::size_of::<Vector<D>>()
            + self.rows.capacity() * 4
            + self.numbering_bytes()
    }

    /// Bytes of the row numbering's box-wide bitmaps and counts: about 0.19 bytes per grid
    /// node (a bit, and a 4-byte count per 64 nodes).
    pub fn numbering_bytes(&self) -> usize {
        (self.marks.capacity() + self.summary.capacity()) * 8 + self.rank.capacity() * 4
    }
}

/// The particles of one material, as physics operators see them.
#[derive(Clone, Debug)]
pub struct GroupView {
    /// Material name in the scene.
    pub name: String,
    /// Particle indices.
    pub range: Range<usize>,
}

/// What a physics operator sees of the particles (read only; shared fields are apart).
pub struct ParticleView<'a, const D: usize> {
    /// Current positions.
    pub position: &'a [Vector<D>],
    /// Masses.
    pub mass: &'a [f64],
    /// Reference volumes (m² per unit thickness in 2D).
    pub volume0: &'a [f64],
    /// Deformation gradients (current volume is `det F · volume0`).
    pub deformation_gradient: &'a [Matrix<D>],
    /// Cauchy stresses after the last stress update.
    pub stress: &'a [Matrix<D>],
    /// Material groups.
    pub groups: &'a [GroupView],
    /// Contact field of each particle (numbered as [`crate::scene::ContactSection::fields`]);
    /// empty in a scene without a `contact` section.
    pub contact_field: &'a [u8],
}

/// A problem that stops the run, reported by a physics operator.
#[derive(Clone, Debug, PartialEq)]
pub struct PhysicsFault {
    /// The field at fault (`temperature`).
    pub field: String,
    /// Particle (storage index), if one is at fault.
    pub particle: Option<usize>,
    /// The offending value.
    pub value: f64,
    /// What happened.
    pub message: String,
}

/// A table of numbers an operator keeps over the run (one row per void, a fill history);
/// written to the metrics and to the result store's `tables/<name>` array.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Table {
    /// Column names, one per number in a row.
    pub columns: Vec<String>,
    /// Rows, each with one number per column.
    pub rows: Vec<Vec<f64>>,
}

/// What operators report back: a fault that stops the run, figures and tables for the
/// metrics. It persists over the whole run.
#[derive(Clone, Debug, Default)]
pub struct PhysicsReport {
    /// Set to stop the run with a diagnostic.
    pub fault: Option<PhysicsFault>,
    /// Largest value of each named figure over the run (`thermal.solver_iterations`), or
    /// its latest for a figure recorded with [`PhysicsReport::record_last`].
    pub maxima: Vec<(String, f64)>,
    /// Named tables operators keep over the run (`underfill.voids`), in creation order.
    pub tables: Vec<(String, Table)>,
}

impl PhysicsReport {
    /// Records a figure; the metrics keep its largest value over the run.
    pub fn record_max(&mut self, name: &str, value: f64) {
        match self.maxima.iter_mut().find(|(n, _)| n == name) {
            Some((_, v)) => *v = v.max(value),
            None => self.maxima.push((name.to_string(), value)),
        }
    }

    /// Records a figure whose latest value the metrics keep (the voids still open now).
    pub fn record_last(&mut self, name: &str, value: f64) {
        match self.maxima.iter_mut().find(|(n, _)| n == name) {
            Some((_, v)) => *v = value,
            None => self.maxima.push((name.to_string(), value)),
        }
    }

    /// The table `name`, created empty with `columns` when missing (an existing table keeps
    /// its columns and rows, so operators can add or edit rows in later steps).
    pub fn table_mut(&mut self, name: &str, columns: &[&str]) -> &mut Table {
        let i = match self.tables.iter().position(|(n, _)| n == name) {
            Some(i) => i,
            None => {
                let table = Table {
                    columns: columns.iter().map(|c| c.to_string()).collect(),
                    rows: Vec::new(),
                };
                self.tables.push((name.to_string(), table));
                self.tables.len() - 1
            }
        };
        &mut self.tables[i].1
    }

    /// The table `name`, if an operator created it.
    pub fn table(&self, name: &str) -> Option<&Table> {
        self.tables.iter().find(|(n, _)| n == name).map(|(_, t)| t)
    }

    /// Stops the run (the first fault wins).
    pub fn fail(&mut self, fault: PhysicsFault) {
        if self.fault.is_none() {
            self.fault = Some(fault);
        }
    }
}

/// Everything an operator sees in one stage.
pub struct PhysicsContext<'a, const D: usize> {
    /// Step size, s (0 in [`Stage::Initialise`]).
    pub dt: f64,
    /// Time at the end of the step, s.
    pub time: f64,
    /// The grid (geometry, and the nodal mass of the last P2G).
    pub grid: &'a Grid<D>,
    /// Stencils at the current positions.
    pub interpolation: &'a Interpolation<D>,
    /// Particle data.
    pub particles: ParticleView<'a, D>,
    /// The walls and obstacles (which cells are solid).
    pub boundaries: &'a crate::boundary::Boundaries<D>,
    /// Shared scalar particle fields.
    pub fields: &'a mut ParticleFields,
    /// This operator's grid scratch arrays, one per [`PhysicsLaw::grid_arrays`], each
    /// [`PhysicsLaw::values_per_row`] numbers per row of `interpolation` (row-major by
    /// value: row + k × rows), sized by the core whenever it builds the stencils; they keep
    /// their values between steps while the rows stay.
    pub scratch: &'a mut [Vec<f64>],
    /// Faults and figures.
    pub report: &'a mut PhysicsReport,
}

/// The points in a step where the core calls operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Once before the first step: set initial values of the operator's fields.
    Initialise,
    /// Every step, before any operator advances: evaluate properties (conductivity as a
    /// function of temperature, property mixing by phase).
    Prepare,
    /// Every step: the operator's own transfers and solve (conduction, kinetics).
    Advance,
    /// Every step, after every operator advanced: derived fields (free strain).
    Finish,
}

/// What a plugin author implements for a physics operator: generic over the dimension.
pub trait PhysicsLaw: Send + Sync + 'static {
    /// The scalar particle fields this operator creates.
    fn fields(&self) -> Vec<SharedFieldSpec>;
    /// Fields it reads that other operators create (validation names the missing one).
    fn requires(&self) -> Vec<&'static str> {
        Vec::new()
    }
    /// Grid scratch arrays it needs (each [`PhysicsLaw::values_per_row`] numbers per row).
    fn grid_arrays(&self) -> usize {
        0
    }
    /// Numbers per row in each scratch array (one per thermal group with contact
    /// conductance, say).
    fn values_per_row(&self) -> usize {
        1
    }
    /// Whether the particle stencils must be built for it.
    fn needs_interpolation(&self) -> bool {
        true
    }
    /// Largest stable step of its explicit parts, s (infinite when it has none).
    fn stable_dt<const D: usize>(&self, _ctx: PhysicsContext<'_, D>) -> f64 {
        f64::INFINITY
    }
    /// What the operator keeps between steps outside the particle fields and grid scratch
    /// the core holds, and a checkpoint therefore cannot (`None`: nothing, or only caches
    /// it rebuilds). A scene asking for checkpoints with such an operator is refused.
    fn hidden_state(&self) -> Option<&'static str> {
        None
    }
    /// Runs one stage.
    fn stage<const D: usize>(&self, stage: Stage, ctx: PhysicsContext<'_, D>);
}

/// Object-safe form of [`PhysicsLaw`]; implemented for every law, used by the solver.
pub trait Physics: Send + Sync {
    /// See [`PhysicsLaw::fields`].
    fn fields(&self) -> Vec<SharedFieldSpec>;
    /// See [`PhysicsLaw::requires`].
    fn requires(&self) -> Vec<&'static str>;
    /// See [`PhysicsLaw::grid_arrays`].
    fn grid_arrays(&self) -> usize;
    /// See [`PhysicsLaw::values_per_row`].
    fn values_per_row(&self) -> usize;
    /// See [`PhysicsLaw::needs_interpolation`].
    fn needs_interpolation(&self) -> bool;
    /// See [`PhysicsLaw::hidden_state`].
    fn hidden_state(&self) -> Option<&'static str>;
    /// 2D stable step.
    fn stable_dt_2d(&self, ctx: PhysicsContext<'_, 2>) -> f64;
    /// 3D stable step.
    fn stable_dt_3d(&self, ctx: PhysicsContext<'_, 3>) -> f64;
    /// 2D stage.
    fn stage_2d(&self, stage: Stage, ctx: PhysicsContext<'_, 2>);
    /// 3D stage.
    fn stage_3d(&self, stage: Stage, ctx: PhysicsContext<'_, 3>);
}

impl<T: PhysicsLaw> Physics for T {
    fn fields(&self) -> Vec<SharedFieldSpec> {
        PhysicsLaw::fields(self)
    }
    fn requires(&self) -> Vec<&'static str> {
        PhysicsLaw::requires(self)
    }
    fn grid_arrays(&self) -> usize {
        PhysicsLaw::grid_arrays(self)
    }
    fn values_per_row(&self) -> usize {
        PhysicsLaw::values_per_row(self)
    }
    fn needs_interpolation(&self) -> bool {
        PhysicsLaw::needs_interpolation(self)
    }
    fn hidden_state(&self) -> Option<&'static str> {
        PhysicsLaw::hidden_state(self)
    }
    fn stable_dt_2d(&self, ctx: PhysicsContext<'_, 2>) -> f64 {
        self.stable_dt::<2>(ctx)
    }
    fn stable_dt_3d(&self, ctx: PhysicsContext<'_, 3>) -> f64 {
        self.stable_dt::<3>(ctx)
    }
    fn stage_2d(&self, stage: Stage, ctx: PhysicsContext<'_, 2>) {
        self.stage::<2>(stage, ctx)
    }
    fn stage_3d(&self, stage: Stage, ctx: PhysicsContext<'_, 3>) {
        self.stage::<3>(stage, ctx)
    }
}

/// Builds one physics operator from the scene's `physics.<name>` section.
pub trait PhysicsFactory: Send + Sync {
    /// The section's key under `physics` (`thermal`).
    fn name(&self) -> &'static str;
    /// JSON Schema of the section.
    fn schema(&self) -> serde_json::Value;
    /// Reads and checks the section (materials are named by the scene); issues carry full
    /// JSON paths below `path`.
    fn build(
        &self,
        section: &serde_json::Value,
        path: &str,
        scene: &Scene,
    ) -> Result<Arc<dyn Physics>, Vec<Issue>>;
    /// Whether the operator's node arrays cover only the nodes the particles' stencils
    /// reach (compact rows, [`Interpolation`]'s `compact`), so that a scene naming it keeps
    /// a sparse grid's small estimate in the budget check; `false` (arrays over the whole
    /// grid box) by default.
    fn node_arrays_follow_particles(&self) -> bool {
        false
    }
}

/// Checks a typed section and builds the operator (see [`TypedPhysicsFactory`]).
pub type BuildPhysicsFn<P> = fn(P, &str, &Scene) -> Result<Arc<dyn Physics>, Vec<Issue>>;

/// A [`PhysicsFactory`] for a parameter struct `P` (serde + schemars): deserialises with
/// JSON-path errors, derives the schema, and calls `build`.
pub struct TypedPhysicsFactory<P> {
    name: &'static str,
    build: BuildPhysicsFn<P>,
    compact_rows: bool,
}

impl<P> TypedPhysicsFactory<P> {
    /// A factory for the section `physics.<name>`.
    pub fn new(name: &'static str, build: BuildPhysicsFn<P>) -> Self {
        Self {
            name,
            build,
            compact_rows: false,
        }
    }

    /// Declares that the operator sizes its node arrays by the stencils' rows (see
    /// [`PhysicsFactory::node_arrays_follow_particles`]).
    pub fn with_compact_rows(mut self) -> Self {
        self.compact_rows = true;
        self
    }
}

impl<P> PhysicsFactory for TypedPhysicsFactory<P>
where
    P: serde::de::DeserializeOwned + schemars::JsonSchema + Send + Sync,
{
    fn name(&self) -> &'static str {
        self.name
    }

    fn schema(&self) -> serde_json::Value {
        crate::section::section_schema::<P>()
    }

    fn build(
        &self,
        section: &serde_json::Value,
        path: &str,
        scene: &Scene,
    ) -> Result<Arc<dyn Physics>, Vec<Issue>> {
        let typed: P = crate::scene::deserialize_at(section, path).map_err(|e| vec![e])?;
        (self.build)(typed, path, scene)
    }

    fn node_arrays_follow_particles(&self) -> bool {
        self.compact_rows
    }
}

/// A material property that may depend on temperature: a number, or a table of
/// `[temperature, value]` rows interpolated linearly (held constant past either end).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Property {
    /// The same value at every temperature.
    Constant(f64),
    /// `[[T0, v0], [T1, v1], ...]` with T increasing, kelvin.
    Table(Vec<[f64; 2]>),
}

impl Property {
    /// The value at temperature `t`.
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        match self {
            Property::Constant(v) => *v,
            Property::Table(rows) => {
                let first = rows[0];
                if t <= first[0] {
                    return first[1];
                }
                for pair in rows.windows(2) {
                    let (a, b) = (pair[0], pair[1]);
                    if t <= b[0] {
                        let s = (t - a[0]) / (b[0] - a[0]);
                        return a[1] + s * (b[1] - a[1]);
                    }
                }
                rows[rows.len() - 1][1]
            }
        }
    }

    /// Problems with the property at `path`: every value must pass `valid` (described by
    /// `what`); a table needs a row and strictly increasing temperatures.
    pub fn check(&self, path: &str, what: &str, valid: impl Fn(f64) -> bool) -> Vec<Issue> {
        let mut issues = Vec::new();
        match self {
            Property::Constant(v) => {
                if !valid(*v) {
                    issues.push(Issue::new(path, format!("must be {what} (got {v})")));
                }
            }
            Property::Table(rows) => {
                if rows.is_empty() {
                    issues.push(Issue::new(path, "a table needs at least one row"));
                }
                for (i, row) in rows.iter().enumerate() {
                    if !valid(row[1]) {
                        issues.push(Issue::new(
                            format!("{path}[{i}][1]"),
                            format!("must be {what} (got {})", row[1]),
                        ));
                    }
                    if !row[0].is_finite() {
                        issues.push(Issue::new(
                            format!("{path}[{i}][0]"),
                            "temperature must be finite",
                        ));
                    }
                    if i > 0 && row[0] <= rows[i - 1][0] {
                        issues.push(Issue::new(
                            format!("{path}[{i}][0]"),
                            "temperatures must increase down the table",
                        ));
                    }
                }
            }
        }
        issues
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn property_tables_interpolate_and_hold_their_ends() {
        let p = Property::Table(vec![[300.0, 1.0], [400.0, 3.0]]);
        assert_eq!(p.at(200.0), 1.0);
        assert!((p.at(350.0) - 2.0).abs() < 1e-12);
        assert_eq!(p.at(500.0), 3.0);
        assert!(p.check("k", "> 0", |v| v > 0.0).is_empty());
        let bad = Property::Table(vec![[400.0, 1.0], [300.0, -1.0]]);
        let issues = bad.check("k", "> 0", |v| v > 0.0);
        assert_eq!(issues.len(), 2);
        assert_eq!(issues[0].path, "k[1][1]");
    }

    #[test]
    fn table_mut_creates_once_and_keeps_rows_between_calls() {
        let mut report = PhysicsReport::default();
        assert!(report.table("voids").is_none());
        report
            .table_mut("voids", &["x", "volume"])
            .rows
            .push(vec![1.0, 2.0]);
        // A later call (a later step) finds the same table; its columns argument is ignored.
        let voids = report.table_mut("voids", &["other"]);
        assert_eq!(voids.columns, ["x", "volume"]);
        voids.rows[0][1] = 3.0;
        voids.rows.push(vec![4.0, 5.0]);
        report.table_mut("history", &["t"]);
        assert_eq!(report.tables.len(), 2);
        assert_eq!(report.tables[0].0, "voids");
        assert_eq!(
            report.table("voids").map(|t| t.rows.clone()),
            Some(vec![vec![1.0, 3.0], vec![4.0, 5.0]])
        );
        assert_eq!(report.table("history").map(|t| t.rows.len()), Some(0));
    }

    #[test]
    fn many_mut_hands_out_distinct_fields() {
        let mut f = ParticleFields::default();
        f.add(
            SharedFieldSpec {
                name: "a",
                initial: 1.0,
            },
            2,
        );
        f.add(
            SharedFieldSpec {
                name: "b",
                initial: 2.0,
            },
            2,
        );
        let [a, b, c] = f.many_mut(["a", "b", "c"]);
        a.unwrap()[0] = 5.0;
        assert_eq!(b.unwrap()[1], 2.0);
        assert!(c.is_none());
        assert_eq!(f.get("a").unwrap(), &[5.0, 1.0]);
    }
}
