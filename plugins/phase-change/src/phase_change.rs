//! The phase-change operator: property mixing, latent heat, cure kinetics, free strains.

use crate::cure::{CureParameters, TemperaturePath};
use crate::parameters::PhaseChangeParameters;
use mpm_core::physics::{
    FREE_STRAIN, GroupView, HEAT_RELEASE, PhysicsContext, PhysicsLaw, SharedFieldSpec, Stage,
};
use std::sync::Mutex;

/// Melting, solidification and cure on the particles (see the crate documentation).
pub struct PhaseChange {
    params: PhaseChangeParameters,
    cure: bool,
    free_strain: bool,
    /// Each particle's (cure, temperature) at the step's start, kept by the kinetics'
    /// predictor for their corrector after conduction (empty outside a step).
    step_start: Mutex<Vec<[f64; 2]>>,
}

impl PhaseChange {
    /// The operator for checked parameters.
    pub fn new(params: PhaseChangeParameters) -> Self {
        Self {
            cure: params.has_cure(),
            free_strain: params.has_free_strain(),
            params,
            step_start: Mutex::new(Vec::new()),
        }
    }

    /// The groups whose material cures, with its cure parameters.
    fn curing<'a>(
        &'a self,
        groups: &'a [GroupView],
    ) -> impl Iterator<Item = (&'a CureParameters, &'a GroupView)> + 'a {
        groups.iter().filter_map(|g| {
            let params = self.params.materials.get(&g.name)?.cure.as_ref()?;
            Some((params, g))
        })
    }

    fn initialise<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let [Some(t), Some(f), cure, tg] =
            ctx.fields
                .many_mut(["temperature", "solid_fraction", "cure", "glass_transition"])
        else {
            return;
        };
        let (mut cure, mut tg) = (cure, tg);
        for g in ctx.particles.groups {
            let Some(m) = self.params.materials.get(&g.name) else {
                continue;
            };
            for p in g.range.clone() {
                if let Some(melt) = &m.melting {
                    f[p] = melt.initial_fraction(t[p]);
                }
                if let Some(c) = &m.cure {
                    let a = c.initial_cure;
                    if let Some(cure) = cure.as_deref_mut() {
                        cure[p] = a;
                    }
                    if let (Some(tg), Some(gt)) = (tg.as_deref_mut(), &c.glass_transition) {
                        tg[p] = gt.at(a);
                    }
                    f[p] = if a >= c.gel_point { 1.0 } else { 0.0 };
                }
            }
        }
    }

    /// Cure kinetics over the coming step, the predictor: the degree of cure advances at
    /// the particles' temperatures held, and its heat of reaction goes to the
    /// `heat_release` field, which the conduction of this step spreads through the grid
    /// like any heat source. [`PhaseChange::correct_cure`] takes the step again after
    /// conduction. (A predictor that sees its own heat as if adiabatic releases too much
    /// near the gel point; conduction carries the excess off and the corrector can only
    /// take it back from the particle: the final cure of the cure example fell 0.04 short
    /// at 30 s steps, against 0.002 over with this one.)
    fn cure<const D: usize>(&self, ctx: &mut PhysicsContext<'_, D>) {
        let dt = ctx.dt;
        if dt <= 0.0 || !self.cure {
            return;
        }
        let [Some(t), Some(cure), Some(heat)] =
            ctx.fields.many_mut(["temperature", "cure", HEAT_RELEASE])
        else {
            return;
        };
        let pv = &ctx.particles;
        heat.fill(0.0);
        let mut start = self.step_start.lock().unwrap_or_else(|e| e.into_inner());
        start.clear();
        start.extend(cure.iter().zip(t.iter()).map(|(&a, &t)| [a, t]));
        for (params, g) in self.curing(pv.groups) {
            for p in g.range.clone() {
                let a = params.advance_along(cure[p], TemperaturePath::constant(t[p]), dt);
                let rho0 = pv.mass[p] / pv.volume0[p];
                heat[p] = rho0 * params.heat_of_reaction * (a - cure[p]);
                cure[p] = a;
            }
        }
    }

    /// Mixes conductivity and specific heat of melting materials by solid fraction.
    fn mix<const D: usize>(&self, mut ctx: PhysicsContext<'_, D>) {
        self.cure(&mut ctx);
        let [Some(f), Some(k), Some(c)] =
            ctx.fields
                .many_mut(["solid_fraction", "conductivity", "specific_heat"])
        else {
            return;
        };
        for g in ctx.particles.groups {
            let Some(melt) = self
                .params
                .materials
                .get(&g.name)
                .and_then(|m| m.melting.as_ref())
            else {
                continue;
            };
            for p in g.range.clone() {
                let (kk, cc, _) = melt.mix(f[p]);
                k[p] = kk;
                c[p] = cc;
            }
        }
    }

    /// The kinetics' corrector after conduction: the cure advances again from the step's
    /// start along the temperature conduction gave (linear from the start's to the
    /// conducted one, which carries the predicted reaction heat), plus the heat of the
    /// cure's departure from the prediction, which stays in the particle
    /// ([`TemperaturePath`]; in an adiabatic cell this is the exact adiabatic rise). The
    /// particle then cures as its own temperature history says, to second order in the
    /// step; before, the kinetics saw an adiabatic rise that conduction to the die did not
    /// leave, and ran ahead of that history by up to 0.05 in cure at 30 s steps.
    fn correct_cure<const D: usize>(&self, ctx: &mut PhysicsContext<'_, D>) {
        let mut start = self.step_start.lock().unwrap_or_else(|e| e.into_inner());
        let dt = ctx.dt;
        let [Some(t), Some(c), Some(cure)] =
            ctx.fields
                .many_mut(["temperature", "specific_heat", "cure"])
        else {
            return;
        };
        if dt <= 0.0 || start.len() != cure.len() {
            start.clear();
            return;
        }
        for (params, g) in self.curing(ctx.particles.groups) {
            for p in g.range.clone() {
                let [a0, t0] = start[p];
                let heating = params.heat_of_reaction / c[p];
                let path = TemperaturePath {
                    start: t0,
                    end: t[p],
                    heating,
                    released: cure[p] - a0,
                };
                let a = params.advance_along(a0, path, dt);
                t[p] += heating * (a - cure[p]);
                cure[p] = a;
            }
        }
        start.clear();
    }

    /// Latent heat and cure after conduction.
    fn react<const D: usize>(&self, mut ctx: PhysicsContext<'_, D>) {
        if self.cure {
            self.correct_cure(&mut ctx);
        }
        let [Some(t), Some(f), Some(c), cure, tg] = ctx.fields.many_mut([
            "temperature",
            "solid_fraction",
            "specific_heat",
            "cure",
            "glass_transition",
        ]) else {
            return;
        };
        let (cure, mut tg) = (cure, tg);
        for g in ctx.particles.groups {
            let Some(m) = self.params.materials.get(&g.name) else {
                continue;
            };
            for p in g.range.clone() {
                if let Some(melt) = &m.melting {
                    let (tt, ff) = melt.recover(t[p], f[p], c[p]);
                    t[p] = tt;
                    f[p] = ff;
                }
                if let (Some(params), Some(cure)) = (&m.cure, cure.as_deref()) {
                    if let (Some(tg), Some(gt)) = (tg.as_deref_mut(), &params.glass_transition) {
                        tg[p] = gt.at(cure[p]);
                    }
                    if cure[p] >= params.gel_point {
                        f[p] = 1.0;
                    }
                }
            }
        }
    }

    /// Adds density-change and shrinkage strains to the free strain (thermal set it).
    fn strain<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let [Some(f), Some(fs), cure] =
            ctx.fields.many_mut(["solid_fraction", FREE_STRAIN, "cure"])
        else {
            return;
        };
        let pv = &ctx.particles;
        for g in pv.groups {
            let Some(m) = self.params.materials.get(&g.name) else {
                continue;
            };
            for p in g.range.clone() {
                if let Some(melt) = &m.melting {
                    // Linear strain of the density change from the particle's start
                    // density (mass over reference volume).
                    let (_, _, rho) = melt.mix(f[p]);
                    let rho0 = pv.mass[p] / pv.volume0[p];
                    fs[p] += (rho0 / rho).cbrt() - 1.0;
                }
                if let (Some(c), Some(cure)) = (&m.cure, cure.as_deref()) {
                    fs[p] -= c.shrinkage * (cure[p] - c.initial_cure) / 3.0;
                }
            }
        }
    }
}

impl PhysicsLaw for PhaseChange {
    fn fields(&self) -> Vec<SharedFieldSpec> {
        let mut f = vec![SharedFieldSpec {
            name: "solid_fraction",
            initial: 1.0,
        }];
        if self.cure {
            f.push(SharedFieldSpec {
                name: "cure",
                initial: 0.0,
            });
            f.push(SharedFieldSpec {
                name: "glass_transition",
                initial: 0.0,
            });
            f.push(SharedFieldSpec {
                name: HEAT_RELEASE,
                initial: 0.0,
            });
        }
        if self.free_strain {
            f.push(SharedFieldSpec {
                name: FREE_STRAIN,
                initial: 0.0,
            });
        }
        f
    }

    fn requires(&self) -> Vec<&'static str> {
        vec!["temperature", "conductivity", "specific_heat"]
    }

    fn needs_interpolation(&self) -> bool {
        false
    }

    fn stage<const D: usize>(&self, stage: Stage, ctx: PhysicsContext<'_, D>) {
        match stage {
            Stage::Initialise => self.initialise(ctx),
            Stage::Prepare => self.mix(ctx),
            Stage::Advance => self.react(ctx),
            Stage::Finish => self.strain(ctx),
        }
    }
}
