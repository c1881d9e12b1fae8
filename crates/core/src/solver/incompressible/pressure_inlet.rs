//! Inlets at a set pressure (`inflow` bodies with `pressure` and `volume`): a reservoir
//! behind the inlet face holds the liquid at a gauge pressure, and the liquid enters as
//! fast as the flow it drives carries it away from the face.
//!
//! While the flow lasts (from `start` until `end` or until the reservoir's particles have
//! all entered) the projection holds the pressure-boundary nodes at the inlet face at the
//! reservoir's pressure instead of the free surface's: the free-surface nodes (touching an
//! empty cell) that lie across the face (its extent plus half a cell) from a cell before
//! the face to half a cell past it. Behind the face the cells are empty (the waiting
//! particles have no volume), so those nodes are free surface, and the Poisson solve then
//! sees the reservoir's pressure on the face, the free surface's 0 (or Laplace pressure)
//! at the flow front and walls' ∂p/∂n = 0: the flow through the face is the one that
//! pressure drives.
//!
//! The liquid enters after G2P, where the flow has made room for it: each lattice point
//! across the face owns a strip one spacing h wide (h × h in 3D) and `ZONE_LAYERS`
//! spacings deep past the face, and when the liquid particles in a strip hold less than
//! that volume, as many particles enter the strip as make up the deficit (rounded),
//! the last one half a spacing past the face, each with the strip's mean velocity along
//! the direction (at least 0) plus the inlet's own. Strip by strip, so that the liquid
//! enters where the flow carries it away (fast in the middle of a channel, not at its
//! no-slip walls): flat layers by a mean speed piled particles up at the walls and left
//! the middle short, and the projection's volume source, pushing the piles apart, sped
//! the flow up. The waiting particles enter in their order, each at the strip it is
//! given. On its first step an empty strip takes `ZONE_LAYERS` particles at rest, so that
//! an empty channel has liquid for the pressure to push. The inlet takes no liquid back:
//! liquid pushed back through the face stays liquid behind it. With surface tension the
//! colour counts the nodes just behind a flowing face as full (`reservoir_nodes`): the
//! face is no free surface, and taken for one it held a 1 mm gap's liquid at 0.19 mm
//! against 100 Pa. Since liquid enters only
//! where there is room, a scene whose inlets are all pressure inlets has no volume source
//! in its pressure equation (`Inflows::has_inlets`): with it, the source's corrections of
//! the particles' drift in a sheared channel kicked the pressure to twice the inlet's.
//!
//! The step: a liquid at rest gives the velocity CFL no bound, and the reservoir's pressure
//! accelerates it within a step (an empty channel's first layers by Δp/(ρ·dx)). So, as
//! gravity adds √(dx·|g|) to the speed the step is bounded by, a flowing inlet adds √(dx·a),
//! with a the change of its fastest strip speed in the last step per unit time, at most
//! Bernoulli's √(2|Δp|/ρ), which it adds while the liquid at its face is still at rest.
//! Without it the step after the opening was set by the first small speeds and the
//! accelerating liquid inverted a particle (an empty 1 mm gap at 100 Pa, step 18).
//!
//! The particles let in, the strip speed and its change are kept in checkpoints and
//! carried across stages.

use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::grid::{Grid, node_position};
use crate::particles::Particles;
use crate::scene::{INJECTED, InflowLayout};

/// Checkpoint array: per pressure inlet, in the order of the bodies, the particles it has
/// let in, its last strip speed and that speed's change per unit time.
const STATE: &str = "inflow.pressure_inlets";

/// Spacings past the face within which a pressure inlet reads its strips (more than the
/// liquid moves in a step at a CFL number up to 1 with two particles per cell).
const ZONE_LAYERS: f64 = 3.0;

/// The state of one pressure inlet.
#[derive(Clone, Debug)]
pub(super) struct PressureDrive {
    /// The reservoir's gauge pressure, Pa.
    pub(super) pressure: f64,
    /// The liquid's density, kg/m³.
    density: f64,
    /// Particles let in before this step.
    before: usize,
    /// Particles let in so far (this step's included, once it has stepped).
    entered: usize,
    /// The largest strip speed of the last step, m/s, and how fast it changed in that
    /// step, m/s².
    speed: f64,
    acceleration: f64,
    /// The lattice point of each square-lattice place across the face (`None` outside a
    /// round inlet), `side` × `side` (× 1 in 2D), row by row as the layout lays them.
    places: Vec<Option<usize>>,
    /// Lattice points along one tangent.
    side: usize,
    /// Per lattice point: the liquid volume in its strip, the volume-weighted speed sum and
    /// the distance of the rearmost particle past the face (the strip's depth if empty).
    strip_volume: Vec<f64>,
    strip_flux: Vec<f64>,
    strip_rear: Vec<f64>,
    /// This step's entries: the lattice point and the distance past the face of each.
    batch: Vec<(usize, f64)>,
}

impl PressureDrive {
    /// A closed inlet at `pressure` of a liquid of `density` laid out as `layout` (nothing
    /// has entered).
    pub(super) fn new(pressure: f64, density: f64, layout: &InflowLayout) -> Self {
        let h = layout.spacing;
        let n = layout.offsets.len();
        // The layout lays its points on a square lattice of spacing h centred on the face
        // (the round inlet's corners left out): find each point's place on it.
        let coordinate = |o: &[f64; 3], t: &[f64; 3]| -> f64 { (0..3).map(|a| o[a] * t[a]).sum() };
        let [t1, t2] = layout.tangents;
        let extent = layout
            .offsets
            .iter()
            .map(|o| coordinate(o, &t1).abs().max(coordinate(o, &t2).abs()))
            .fold(0.0, f64::max);
        let side = ((2.0 * extent / h).round() as usize + 1).max(1);
        let second = if t2.iter().all(|x| *x == 0.0) {
            1
        } else {
            side
        };
        let mut places = vec![None; side * second];
        for (k, o) in layout.offsets.iter().enumerate() {
            if let Some(place) =
                lattice_place(coordinate(o, &t1), coordinate(o, &t2), h, side, second)
            {
                places[place] = Some(k);
            }
        }
        Self {
            pressure,
            density,
            before: 0,
            entered: 0,
            speed: 0.0,
            acceleration: 0.0,
            places,
            side,
            strip_volume: vec![0.0; n],
            strip_flux: vec![0.0; n],
            strip_rear: vec![0.0; n],
            batch: Vec::new(),
        }
    }

    /// Whether the flow runs at `time`: after its start, before its end, and while the
    /// reservoir still holds a particle.
    pub(super) fn flowing(&self, layout: &InflowLayout, time: f64) -> bool {
        time >= layout.start && time < layout.end && self.entered < layout.particles()
    }

    /// While the flow runs at `time`, the speed the reservoir's pressure may add to the
    /// liquid within a step, for the step bound (as gravity's √(dx·|g|)): √(dx·a) with a
    /// the change of the fastest strip speed over the last step per unit time, at most
    /// Bernoulli's √(2|Δp|/ρ), which is the bound while the liquid at the face is still at
    /// rest; 0 when the flow does not run.
    pub(super) fn added_speed(&self, layout: &InflowLayout, time: f64, dx: f64) -> f64 {
        if !self.flowing(layout, time) {
            return 0.0;
        }
        let bernoulli = (2.0 * self.pressure.abs() / self.density).sqrt();
        if self.speed == 0.0 {
            bernoulli
        } else {
            (dx * self.acceleration).sqrt().min(bernoulli)
        }
    }

    /// Where the inlet's `index`-th particle (in its order) enters in this step, if it
    /// does: its lattice point across the face, its distance past the face and its speed
    /// along the direction.
    pub(super) fn entry(&self, index: usize) -> Option<(usize, f64, f64)> {
        if index < self.before || index >= self.entered {
            return None;
        }
        let (k, distance) = *self.batch.get(index - self.before)?;
        let volume = self.strip_volume[k];
        let speed = if volume > 0.0 {
            (self.strip_flux[k] / volume).max(0.0)
        } else {
            0.0
        };
        Some((k, distance, speed))
    }

    /// After G2P of a step of `dt` that started at `time`: reads the liquid in each strip
    /// past the face and lets in the particles that make up its deficit (see the module's
    /// documentation).
    pub(super) fn step<const D: usize>(
        &mut self,
        layout: &InflowLayout,
        particles: &Particles<D>,
        time: f64,
        dt: f64,
    ) {
        self.before = self.entered;
        self.batch.clear();
        if !self.flowing(layout, time) {
            self.speed = 0.0;
            self.acceleration = 0.0;
            return;
        }
        self.read_strips(layout, particles, time + dt);
        let h = layout.spacing;
        let mut fastest: f64 = 0.0;
        let room = layout.particles() - self.entered;
        for k in 0..layout.offsets.len() {
            let volume = self.strip_volume[k];
            if volume > 0.0 {
                fastest = fastest.max(self.strip_flux[k] / volume);
            }
            // Behind the rearmost particle, one spacing apart down to the face.
            let rear = self.strip_rear[k];
            let due = ((rear / h).floor() as usize).min(room - self.batch.len());
            for m in 1..=due {
                self.batch.push((k, rear - m as f64 * h));
            }
        }
        let fastest = fastest.max(0.0);
        self.acceleration = (fastest - self.speed).abs() / dt;
        self.speed = fastest;
        self.entered += self.batch.len();
    }

    /// The liquid volume and volume-weighted speed along the direction (less the inlet's
    /// own) in each lattice point's strip at `time`.
    fn read_strips<const D: usize>(
        &mut self,
        layout: &InflowLayout,
        particles: &Particles<D>,
        time: f64,
    ) {
        self.strip_volume.fill(0.0);
        self.strip_flux.fill(0.0);
        let ahead = ZONE_LAYERS * layout.spacing;
        self.strip_rear.fill(ahead);
        let centre = layout.center_at(time);
        let injected = particles.shared.get(INJECTED);
        let [t1, t2] = layout.tangents;
        let second = self.places.len() / self.side;
        let any_held = particles.any_held();
        for i in 0..particles.len() {
            let v0 = particles.volume0[i];
            // Waiting particles and held solids are no liquid at the face.
            if v0 <= 0.0
                || injected.is_some_and(|f| f[i] < 0.5)
                || (any_held && particles.is_held(i))
            {
                continue;
            }
            let x = &particles.position[i];
            let mut r = [0.0; 3];
            for a in 0..D {
                r[a] = x[a] - centre[a];
            }
            let along: f64 = (0..3).map(|a| r[a] * layout.direction[a]).sum();
            // From half a spacing behind the face: a particle that drifted just behind it
            // still holds the strip's rear (a new one on top of it kicked the flow).
            if !(-0.5 * layout.spacing..ahead).contains(&along) {
                continue;
            }
            let a1: f64 = (0..3).map(|a| r[a] * t1[a]).sum();
            let a2: f64 = (0..3).map(|a| r[a] * t2[a]).sum();
            let Some(k) = lattice_place(a1, a2, layout.spacing, self.side, second)
                .and_then(|place| self.places[place])
            else {
                continue;
            };
            let v = &particles.velocity[i];
            let speed: f64 = (0..D)
                .map(|a| (v[a] - layout.inlet_velocity[a]) * layout.direction[a])
                .sum();
            self.strip_volume[k] += v0;
            self.strip_flux[k] += v0 * speed;
            self.strip_rear[k] = self.strip_rear[k].min(along);
        }
    }
}

/// The place on a `side` × `second` square lattice of spacing `h`, centred on the face,
/// of the point at tangent coordinates (`a1`, `a2`); `None` off the lattice.
fn lattice_place(a1: f64, a2: f64, h: f64, side: usize, second: usize) -> Option<usize> {
    let index = |a: f64, n: usize| {
        let i = (a / h + 0.5 * n as f64).floor();
        (i >= 0.0 && i < n as f64).then_some(i as usize)
    };
    let i = index(a1, side)?;
    let j = if second == 1 { 0 } else { index(a2, second)? };
    Some(i * second + j)
}

/// Sets the reservoir's pressure on the free-surface nodes (`free` ≤ 0) of every flowing
/// pressure inlet's face, for the projection of the step that starts at `time`, less the
/// pressure `kept(node)` the incremental projection (implicit viscosity) kept there, and
/// adds those nodes to `held`.
pub(super) fn hold_pressure<'a, const D: usize>(
    inlets: impl Iterator<Item = (&'a InflowLayout, &'a PressureDrive)>,
    grid: &Grid<D>,
    time: f64,
    free: &[f64],
    kept: impl Fn(usize) -> f64,
    pressure: &mut [f64],
    held: &mut Vec<usize>,
) {
    let dx = grid.dx;
    for (layout, drive) in inlets {
        if !drive.flowing(layout, time) {
            continue;
        }
        let centre = layout.center_at(time);
        // The nodes within the face's extent and two cells of its centre, per axis.
        let reach = layout.half_width + 2.0 * dx;
        let mut low = [0usize; 3];
        let mut high = [0usize; 3];
        for d in 0..D {
            let index = |x: f64| ((x - grid.origin[d]) * grid.inv_dx).floor();
            let last = grid.nodes[d] as f64 - 1.0;
            low[d] = index(centre[d] - reach).clamp(0.0, last) as usize;
            high[d] = (index(centre[d] + reach) + 1.0).clamp(0.0, last) as usize;
        }
        for k in low[2]..=high[2] {
            for j in low[1]..=high[1] {
                for i in low[0]..=high[0] {
                    let ijk = [i, j, k];
                    let node: usize = (0..D).map(|d| ijk[d] * grid.stride[d]).sum();
                    if free[node] > 0.0 {
                        continue;
                    }
                    let position = node_position(&grid.origin, dx, ijk);
                    let mut x = [0.0; 3];
                    x[..D].copy_from_slice(position.as_slice());
                    if layout.reaches(&centre, &x, dx * (1.0 + 1e-9), 0.5 * dx, dx) {
                        pressure[node] = drive.pressure - kept(node);
                        held.push(node);
                    }
                }
            }
        }
    }
}

/// The nodes from half a cell to three cells behind every flowing pressure inlet's face,
/// across its extent, into `out`: the reservoir's liquid, which the surface tension's colour
/// counts as full so that the face is not taken for a free surface (surface_tension.rs).
pub(super) fn reservoir_nodes<'a, const D: usize>(
    inlets: impl Iterator<Item = (&'a InflowLayout, &'a PressureDrive)>,
    grid: &Grid<D>,
    time: f64,
    out: &mut Vec<usize>,
) {
    out.clear();
    let dx = grid.dx;
    for (layout, drive) in inlets {
        if !drive.flowing(layout, time) {
            continue;
        }
        let centre = layout.center_at(time);
        let reach = layout.half_width + 4.0 * dx;
        let mut low = [0usize; 3];
        let mut high = [0usize; 3];
        for d in 0..D {
            let index = |x: f64| ((x - grid.origin[d]) * grid.inv_dx).floor();
            let last = grid.nodes[d] as f64 - 1.0;
            low[d] = index(centre[d] - reach).clamp(0.0, last) as usize;
            high[d] = (index(centre[d] + reach) + 1.0).clamp(0.0, last) as usize;
        }
        for k in low[2]..=high[2] {
            for j in low[1]..=high[1] {
                for i in low[0]..=high[0] {
                    let ijk = [i, j, k];
                    let node: usize = (0..D).map(|d| ijk[d] * grid.stride[d]).sum();
                    let position = node_position(&grid.origin, dx, ijk);
                    let mut x = [0.0; 3];
                    x[..D].copy_from_slice(position.as_slice());
                    if layout.reaches(&centre, &x, 3.0 * dx, -0.5 * dx, 0.0) {
                        out.push(node);
                    }
                }
            }
        }
    }
}

/// Writes the pressure inlets' state (particles let in, strip speed and its change) into
/// a checkpoint.
pub(super) fn save<'a>(drives: impl Iterator<Item = &'a PressureDrive>, c: &mut Checkpoint) {
    let state: Vec<f64> = drives
        .flat_map(|d| [d.entered as f64, d.speed, d.acceleration])
        .collect();
    if !state.is_empty() {
        c.put(STATE, state);
    }
}

/// Reads the `n` pressure inlets' state back. `strict`: a resume, where the checkpoint must
/// hold it; else a stage taking over, which keeps a closed inlet where the stage before
/// had none.
pub(super) fn restore<'a>(
    drives: impl Iterator<Item = &'a mut PressureDrive>,
    n: usize,
    c: &Checkpoint,
    strict: bool,
) -> Result<(), CheckpointError> {
    if n == 0 {
        return Ok(());
    }
    let values = match c.get(STATE, 3 * n) {
        Ok(values) => values,
        Err(e) if strict => return Err(e),
        Err(_) => return Ok(()),
    };
    for (drive, state) in drives.zip(values.chunks_exact(3)) {
        drive.entered = state[0] as usize;
        drive.before = drive.entered;
        drive.speed = state[1];
        drive.acceleration = state[2];
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::test_particles;
    use crate::scene::Inflow;

    /// A 2D inlet 4 spacings wide at the origin, pushing along +x at 100 Pa.
    fn layout(h: f64) -> InflowLayout {
        let inflow: Inflow = serde_json::from_value(serde_json::json!({
            "center": [0.0, 0.0], "direction": [1.0, 0.0], "width": 4.0 * h,
            "pressure": 100.0, "volume": 40.0 * h * h
        }))
        .unwrap();
        inflow.layout(2, h, 1.0)
    }

    #[test]
    fn each_strip_takes_what_makes_up_its_deficit_behind_its_rearmost_particle() {
        let h = 0.5;
        let layout = layout(h);
        assert_eq!(layout.particles(), 40);
        let mut drive = PressureDrive::new(100.0, 1000.0, &layout);
        // An empty face: each of the 4 strips takes three particles, at rest, 2h, h and 0
        // past the face; the liquid is still at rest, so the step bound is Bernoulli's.
        let none = test_particles::<2>(&[], &[], &[]);
        assert!((drive.added_speed(&layout, 0.0, 1.0) - 0.2f64.sqrt()).abs() < 1e-15);
        drive.step(&layout, &none, 0.0, 0.1);
        assert_eq!(drive.entered, 12);
        let first: Vec<_> = (0..3).map(|i| drive.entry(i).unwrap()).collect();
        assert_eq!(first, [(0, 2.0 * h, 0.0), (0, h, 0.0), (0, 0.0, 0.0)]);
        assert_eq!(drive.entry(12), None);
        // Then one particle per strip at 1.2h moving at 0.3 (strip 2 at 0.5): each strip
        // takes one at 0.2h with its strip's speed; the fastest strip sets the bound.
        let across = [-0.75, -0.25, 0.25, 0.75];
        let x: Vec<[f64; 2]> = across.iter().map(|&y| [1.2 * h, y]).collect();
        let mut p = test_particles::<2>(&x, &[h * h; 4], &[]);
        for (i, v) in p.velocity.iter_mut().enumerate() {
            v[0] = if i == 2 { 0.5 } else { 0.3 };
        }
        drive.step(&layout, &p, 0.1, 0.1);
        assert_eq!(drive.entered, 16);
        assert_eq!(drive.entry(11), None);
        let (k, distance, speed) = drive.entry(14).unwrap();
        assert_eq!(k, 2);
        assert!((distance - 0.2 * h).abs() < 1e-15 && speed == 0.5);
        // The fastest strip went from rest to 0.5 in 0.1: √(dx·5), at most Bernoulli's.
        assert!((drive.added_speed(&layout, 0.2, 0.01) - 0.05f64.sqrt()).abs() < 1e-12);
        assert!((drive.added_speed(&layout, 0.2, 1.0) - 0.2f64.sqrt()).abs() < 1e-15);
        assert_eq!(drive.added_speed(&layout, 1.0, 1.0), 0.0);
        // Particles off the face's strips (across or behind it) count for none.
        assert_eq!(lattice_place(1.01, 0.0, h, 4, 1), None);
        assert_eq!(lattice_place(-0.99, 0.0, h, 4, 1), Some(0));
    }
}
