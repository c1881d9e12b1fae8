//! The phase-change operator: property mixing, latent heat, cure kinetics, free strains.

use crate::parameters::PhaseChangeParameters;
use mpm_core::physics::{
    FREE_STRAIN, HEAT_RELEASE, PhysicsContext, PhysicsLaw, SharedFieldSpec, Stage,
};

/// Melting, solidification and cure on the particles (see the crate documentation).
pub struct PhaseChange {
    params: PhaseChangeParameters,
    cure: bool,
    free_strain: bool,
}

impl PhaseChange {
    /// The operator for checked parameters.
    pub fn new(params: PhaseChangeParameters) -> Self {
        Self {
            cure: params.has_cure(),
            free_strain: params.has_free_strain(),
            params,
        }
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

    /// Cure kinetics over the coming step, at the particles' temperatures: the degree of
    /// cure advances (with the temperature rise of its own heat, which the kinetics see),
    /// and the heat of reaction goes to the `heat_release` field, which the conduction of
    /// this step spreads through the grid like any heat source.
    fn cure<const D: usize>(&self, ctx: &mut PhysicsContext<'_, D>) {
        let dt = ctx.dt;
        if dt <= 0.0 || !self.cure {
            return;
        }
        let [Some(t), Some(c), Some(cure), Some(heat)] =
            ctx.fields
                .many_mut(["temperature", "specific_heat", "cure", HEAT_RELEASE])
        else {
            return;
        };
        let pv = &ctx.particles;
        heat.fill(0.0);
        for g in pv.groups {
            let Some(params) = self
                .params
                .materials
                .get(&g.name)
                .and_then(|m| m.cure.as_ref())
            else {
                continue;
            };
            for p in g.range.clone() {
                let (a, _) = params.advance(cure[p], t[p], c[p], dt);
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

    /// Latent heat and cure after conduction.
    fn react<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
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
