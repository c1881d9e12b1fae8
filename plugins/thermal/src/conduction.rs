//! The conduction operator: P2G of heat capacity and thermal energy, the grid solve
//! (explicit or implicit), G2P of the temperature change, and the thermal free strain.

use crate::boundary::Face;
use crate::factored::Factored;
use crate::interface::{Coupling, Interfaces, apply_couplings};
use crate::parameters::HeatPreconditioner;
use crate::parameters::{Integrator, ThermalParameters};
use mpm_core::linear_solvers::conjugate_gradient::{Work, solve, solve_preconditioned};
use mpm_core::math::{Matrix, Vector, determinant};
use mpm_core::physics::{
    FREE_STRAIN, HEAT_RELEASE, Interpolation, PLASTIC_WORK, PhysicsContext, PhysicsFault,
    PhysicsLaw, SharedFieldSpec, Stage,
};
use mpm_core::scene::Scene;
use std::sync::Mutex;

/// Grid scratch arrays: capacity, old and new nodal temperature, sources, convection,
/// held values, conductance diagonal, and four conjugate-gradient vectors.
const ARRAYS: usize = 11;
/// More with contact conductance: each group's particle volume and volume gradient (up to
/// three axes) per node.
const INTERFACE_ARRAYS: usize = 4;
/// Temperatures at or above this stop the run: the conduction has diverged.
const MAX_TEMPERATURE: f64 = 1e5;

/// Heat conduction on the MPM grid (see the crate documentation).
pub struct Thermal {
    params: ThermalParameters,
    domain_min: Vec<f64>,
    domain_max: Vec<f64>,
    expansion: bool,
    plastic_heating: bool,
    factored: Factored,
    /// Thermal groups (one temperature per node and group) and their conductances.
    interfaces: Interfaces,
    /// The interface couplings of the step (reused).
    couplings: Mutex<Vec<Coupling>>,
}

impl Thermal {
    /// The operator for checked parameters, with the thermal groups of `interfaces`.
    pub(crate) fn new(params: ThermalParameters, scene: &Scene, interfaces: Interfaces) -> Self {
        let expansion = params.materials.values().any(|m| m.expansion != 0.0);
        let plastic_heating = params
            .materials
            .values()
            .any(|m| m.taylor_quinney.is_some_and(|b| b > 0.0));
        Self {
            params,
            domain_min: scene.domain.min.clone(),
            domain_max: scene.domain.max.clone(),
            expansion,
            plastic_heating,
            factored: Factored::default(),
            interfaces,
            couplings: Mutex::new(Vec::new()),
        }
    }

    fn initialise<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let Some(temperature) = ctx.fields.get_mut("temperature") else {
            return;
        };
        for g in ctx.particles.groups {
            if let Some(m) = self.params.materials.get(&g.name) {
                temperature[g.range.clone()].fill(m.initial_temperature);
            }
        }
    }

    /// Conductivity and specific heat at the particles' temperatures.
    fn properties<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let [Some(t), Some(k), Some(c)] =
            ctx.fields
                .many_mut(["temperature", "conductivity", "specific_heat"])
        else {
            return;
        };
        for g in ctx.particles.groups {
            let Some(m) = self.params.materials.get(&g.name) else {
                continue;
            };
            for p in g.range.clone() {
                k[p] = m.conductivity.at(t[p]);
                c[p] = m.specific_heat.at(t[p]);
            }
        }
    }

    /// Resets the free strain to the thermal part (other physics add theirs afterwards).
    fn free_strain<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let [Some(t), Some(fs)] = ctx.fields.many_mut(["temperature", FREE_STRAIN]) else {
            return;
        };
        for g in ctx.particles.groups {
            let Some(m) = self.params.materials.get(&g.name) else {
                fs[g.range.clone()].fill(0.0);
                continue;
            };
            let reference = m.reference_temperature.unwrap_or(m.initial_temperature);
            for p in g.range.clone() {
                fs[p] = m.expansion * (t[p] - reference);
            }
        }
    }

    /// One conduction step. With contact conductance every thermal group has its own row
    /// of nodal unknowns (row = node + group × nodes) and the interfaces couple them.
    fn conduct<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let PhysicsContext {
            dt,
            time,
            grid,
            interpolation: it,
            particles: pv,
            fields,
            scratch,
            report,
            ..
        } = ctx;
        if dt <= 0.0 {
            return;
        }
        let [
            Some(temperature),
            Some(conductivity),
            Some(specific_heat),
            plastic_work,
            heat_release,
        ] = fields.many_mut([
            "temperature",
            "conductivity",
            "specific_heat",
            PLASTIC_WORK,
            HEAT_RELEASE,
        ])
        else {
            return;
        };
        let plastic_work: &[f64] = if self.plastic_heating {
            plastic_work.map_or(&[][..], |w| &*w)
        } else {
            &[]
        };
        let heat_release: &[f64] = heat_release.map_or(&[][..], |h| &*h);
        // Rows: the nodes the particles' stencils reach (compact rows), not the whole box.
        let nodes = it.row_count(grid.len());
        let groups = self.interfaces.groups;
        let interface = groups > 1;
        // One value per row and group (the core sizes them with the stencils).
        if scratch.iter().any(|a| a.len() != nodes * groups) {
            // A core fault, not the scene's: stop the run saying so rather than skip the step.
            report.fail(PhysicsFault {
                field: "temperature".into(),
                particle: None,
                value: scratch.first().map_or(0, Vec::len) as f64,
                message: format!(
                    "the conduction's node arrays do not match the {} rows of the stencils",
                    nodes * groups
                ),
            });
            return;
        }
        let (main, extra) = scratch.split_at_mut(ARRAYS.min(scratch.len()));
        let [
            cap,
            t_old,
            t_new,
            source,
            convection,
            fixed,
            kdiag,
            r,
            z,
            p_dir,
            ap,
        ] = main
        else {
            return;
        };
        let (volume_rows, gradient_rows): (&mut [f64], &mut [Vec<f64>]) =
            match extra.split_first_mut() {
                Some((v, g)) if interface && g.len() >= D => (v.as_mut_slice(), &mut g[..D]),
                _ => (&mut [], &mut []),
            };
        for a in [
            &mut *cap,
            &mut *t_old,
            &mut *source,
            &mut *convection,
            &mut *kdiag,
            &mut *volume_rows,
        ] {
            a.fill(0.0);
        }
        for g in gradient_rows.iter_mut() {
            g.fill(0.0);
        }
        fixed.fill(f64::NAN);
        let volume = |p: usize| determinant(&pv.deformation_gradient[p]) * pv.volume0[p];
        let contact_field = pv.contact_field;
        let offset = |p: usize| {
            if interface {
                nodes * self.interfaces.group(contact_field[p])
            } else {
                0
            }
        };

        // P2G: heat capacity, thermal energy, heat sources, conductance diagonal (and, with
        // interfaces, each group's particle volume and volume gradient).
        for g in pv.groups {
            let Some(m) = self.params.materials.get(&g.name) else {
                continue;
            };
            let beta = m.taylor_quinney.unwrap_or(0.0);
            for p in g.range.clone() {
                let v = volume(p);
                let mc = pv.mass[p] * specific_heat[p];
                let mut q = m.heat_source * v;
                if beta > 0.0 && !plastic_work.is_empty() {
                    q += beta * plastic_work[p] * pv.volume0[p] / dt;
                }
                if !heat_release.is_empty() {
                    q += heat_release[p] * pv.volume0[p] / dt;
                }
                let kv = conductivity[p] * v;
                let o = offset(p);
                for e in it.entries(p) {
                    let i = it.node[e] as usize + o;
                    let w = it.weight[e];
                    cap[i] += w * mc;
                    t_old[i] += w * mc * temperature[p];
                    source[i] += w * q;
                    kdiag[i] += kv * it.gradient[e].norm_squared();
                    if interface {
                        volume_rows[i] += w * v;
                        for (axis, row) in gradient_rows.iter_mut().enumerate() {
                            row[i] += v * it.gradient[e][axis];
                        }
                    }
                }
            }
        }
        for i in 0..cap.len() {
            if cap[i] > 0.0 {
                t_old[i] /= cap[i];
            }
        }
        let mut couplings = self
            .couplings
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if interface {
            self.interfaces.couplings::<D>(
                nodes,
                cap,
                volume_rows,
                gradient_rows,
                grid.dx.powi(D as i32),
                &mut couplings,
            );
        }
        let couplings: &[Coupling] = &couplings;

        // Wall conditions where the body touches the faces; a face node shared by groups
        // gives each its share of the face by heat capacity.
        let area = grid.dx.powi(D as i32 - 1);
        let share = |row: usize| {
            if !interface {
                return 1.0;
            }
            let node = row % nodes;
            let total: f64 = (0..groups).map(|g| cap[node + g * nodes]).sum();
            cap[row] / total
        };
        for b in &self.params.boundaries {
            for side in &b.sides {
                let face = Face::new(*side, grid, &self.domain_min, &self.domain_max);
                for row in 0..cap.len() {
                    if cap[row] <= 0.0 {
                        continue;
                    }
                    let c = grid.coords(it.grid_node(row % nodes))[face.axis];
                    if let Some(t) = &b.temperature {
                        if face.on_or_behind(c) {
                            fixed[row] = t.at(time);
                        }
                    } else if face.on(c) {
                        let part = share(row);
                        if let Some(q) = &b.heat_flux {
                            source[row] += q.at(time) * area * part;
                        }
                        if let Some(conv) = &b.convection {
                            let h = conv.coefficient * area * part;
                            convection[row] += h;
                            source[row] += h * conv.ambient.at(time);
                        }
                    }
                }
            }
        }

        let k_of = |p: usize| conductivity[p];
        // y = (K + H_interface) x: conduction within each group, and the interfaces.
        let conduct_and_couple = |x: &[f64], y: &mut [f64]| {
            conductance(
                it,
                pv.deformation_gradient,
                pv.volume0,
                &k_of,
                &offset,
                x,
                y,
            );
            apply_couplings(couplings, x, y);
        };
        match self.params.integrator {
            Integrator::Explicit => {
                conduct_and_couple(t_old, ap);
                for i in 0..cap.len() {
                    t_new[i] = if cap[i] <= 0.0 {
                        0.0
                    } else if fixed[i].is_finite() {
                        fixed[i]
                    } else {
                        t_old[i] + dt * (source[i] - ap[i] - convection[i] * t_old[i]) / cap[i]
                    };
                }
            }
            Integrator::Implicit => {
                // (C + dt·(K + H_interface + H_convection)) T = C·T_old + dt·Q, fixed rows held.
                for c in couplings {
                    kdiag[c.a as usize] += c.conductance;
                    kdiag[c.b as usize] += c.conductance;
                }
                for i in 0..cap.len() {
                    source[i] = cap[i] * t_old[i] + dt * source[i];
                    let free = cap[i] > 0.0 && !fixed[i].is_finite();
                    kdiag[i] = if free {
                        1.0 / (cap[i] + dt * (kdiag[i] + convection[i]))
                    } else {
                        0.0
                    };
                    t_new[i] = if cap[i] <= 0.0 {
                        0.0
                    } else if fixed[i].is_finite() {
                        fixed[i]
                    } else {
                        t_old[i]
                    };
                }
                let (cap, convection) = (&*cap, &*convection);
                let apply = |x: &[f64], y: &mut [f64]| {
                    conduct_and_couple(x, y);
                    for i in 0..x.len() {
                        y[i] = cap[i] * x[i] + dt * (y[i] + convection[i] * x[i]);
                    }
                };
                let mut state = (self.params.preconditioner == HeatPreconditioner::Auto)
                    .then(|| self.factored.state.lock().ok())
                    .flatten();
                let factor = state.as_mut().and_then(|st| {
                    st.factor(
                        it,
                        pv.volume0.len(),
                        |p| conductivity[p] * volume(p),
                        &offset,
                        couplings,
                        cap,
                        convection,
                        kdiag,
                        dt,
                    )
                });
                let work = Work { r, z, p: p_dir, ap };
                let (tol, max) = (self.params.tolerance, self.params.max_iterations);
                let result = match (factor, state.as_mut()) {
                    (Some(factor), Some(st)) => solve_preconditioned(
                        apply,
                        |r: &[f64], z: &mut [f64]| st.precondition(&factor, r, z),
                        kdiag,
                        source,
                        t_new,
                        work,
                        tol,
                        max,
                    ),
                    _ => solve(apply, kdiag, source, t_new, work, tol, max),
                };
                report.record_max("thermal.solver_iterations", result.iterations as f64);
                if !result.converged {
                    report.fail(PhysicsFault {
                        field: "temperature".into(),
                        particle: None,
                        value: result.iterations as f64,
                        message: format!(
                            "the implicit heat solve did not converge in {} iterations (raise physics.thermal.max_iterations or loosen tolerance)",
                            self.params.max_iterations
                        ),
                    });
                }
            }
        }

        // G2P: the nodal temperature change (not the value: no smoothing of the field).
        // Known limit: beside a held face the change carries the jump of the condition,
        // and the first particle layer overshoots it early on (415 K against a 400 K face
        // at 0.02 s in the slab); clamping or interpolating there cost accuracy.
        for (p, t) in temperature.iter_mut().enumerate() {
            let o = offset(p);
            let mut change = 0.0;
            for e in it.entries(p) {
                let i = it.node[e] as usize + o;
                change += it.weight[e] * (t_new[i] - t_old[i]);
            }
            *t += change;
        }
        if let Some(p) = temperature
            .iter()
            .position(|t| !(*t > 0.0 && *t < MAX_TEMPERATURE))
        {
            report.fail(PhysicsFault {
                field: "temperature".into(),
                particle: Some(p),
                value: temperature[p],
                message: format!(
                    "the temperature left the range (0, {MAX_TEMPERATURE:e}) K: the conduction diverged (with the explicit integrator: the step is above its stable step; use solver.cfl or the implicit integrator)"
                ),
            });
        }
    }
}

/// `y = K x`: the conductance matrix `K_ij = Σ_p V_p k_p ∇w_ip·∇w_jp` applied matrix-free
/// through the particles' temperature gradients; particle `p` reads and writes the rows
/// `node + offset(p)` (its thermal group's).
fn conductance<const D: usize>(
    it: &Interpolation<D>,
    deformation_gradient: &[Matrix<D>],
    volume0: &[f64],
    conductivity: &dyn Fn(usize) -> f64,
    offset: &dyn Fn(usize) -> usize,
    x: &[f64],
    y: &mut [f64],
) {
    y.fill(0.0);
    for p in 0..volume0.len() {
        let o = offset(p);
        let mut gradient = Vector::<D>::zeros();
        for e in it.entries(p) {
            gradient += it.gradient[e] * x[it.node[e] as usize + o];
        }
        let s = conductivity(p) * determinant(&deformation_gradient[p]) * volume0[p];
        for e in it.entries(p) {
            y[it.node[e] as usize + o] += s * it.gradient[e].dot(&gradient);
        }
    }
}

impl PhysicsLaw for Thermal {
    fn fields(&self) -> Vec<SharedFieldSpec> {
        let mut f = vec![
            SharedFieldSpec {
                name: "temperature",
                initial: 0.0,
            },
            SharedFieldSpec {
                name: "conductivity",
                initial: 0.0,
            },
            SharedFieldSpec {
                name: "specific_heat",
                initial: 0.0,
            },
        ];
        if self.expansion {
            f.push(SharedFieldSpec {
                name: FREE_STRAIN,
                initial: 0.0,
            });
        }
        if self.plastic_heating {
            f.push(SharedFieldSpec {
                name: PLASTIC_WORK,
                initial: 0.0,
            });
        }
        f
    }

    fn values_per_row(&self) -> usize {
        self.interfaces.groups
    }

    fn grid_arrays(&self) -> usize {
        if self.interfaces.groups > 1 {
            ARRAYS + INTERFACE_ARRAYS
        } else {
            ARRAYS
        }
    }

    fn stable_dt<const D: usize>(&self, ctx: PhysicsContext<'_, D>) -> f64 {
        if self.params.integrator == Integrator::Implicit {
            return f64::INFINITY;
        }
        let (Some(k), Some(c)) = (
            ctx.fields.get("conductivity"),
            ctx.fields.get("specific_heat"),
        ) else {
            return f64::INFINITY;
        };
        let pv = &ctx.particles;
        let dx2 = ctx.grid.dx * ctx.grid.dx;
        let mut dt = f64::INFINITY;
        for p in 0..pv.mass.len() {
            let v = determinant(&pv.deformation_gradient[p]) * pv.volume0[p];
            let rho_c = pv.mass[p] / v * c[p];
            dt = dt.min(rho_c * dx2 / (2.0 * D as f64 * k[p]));
        }
        dt
    }

    fn stage<const D: usize>(&self, stage: Stage, ctx: PhysicsContext<'_, D>) {
        match stage {
            Stage::Initialise => self.initialise(ctx),
            Stage::Prepare => self.properties(ctx),
            Stage::Advance => self.conduct(ctx),
            Stage::Finish => self.free_strain(ctx),
        }
    }
}
