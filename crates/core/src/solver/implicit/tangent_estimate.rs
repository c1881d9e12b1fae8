//! The preconditioner's estimate of each particle's tangent, measured by directional
//! differences of its material's own stress update at the iterate (no plugin is asked for a
//! tangent): the whole tangent C = ∂σ/∂ε, one probe per strain component, so that a
//! particle whose tangent is anisotropic (a creeping solder joint: stiff across its flow
//! direction, soft along it) is preconditioned as it is; an isotropic estimate cannot be
//! both, and the Krylov iterations pay for it. With F-bar the preconditioner splits it
//! ([`deviatoric_part`], [`volumetric_part`]): the deviatoric part acts on the particle,
//! the volumetric part on its patch's mean dilatation.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use super::super::stress_update::update_stress;
use super::residual::a_bar;
use super::workspace::Workspace;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::Matrix;

/// Strain components of a symmetric D×D tensor, (row, column) with row ≤ column: the
/// Voigt order of [`Workspace::tangent`].
pub(super) const fn components(d: usize) -> &'static [(usize, usize)] {
    if d == 2 {
        &[(0, 0), (1, 1), (0, 1)]
    } else {
        &[(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]
    }
}

/// The Voigt index of component (i, k) in [`components`] order.
#[inline]
pub(super) fn voigt<const D: usize>(i: usize, k: usize) -> usize {
    let (a, b) = if i <= k { (i, k) } else { (k, i) };
    if a == b {
        a
    } else {
        // (0, 1) → D, (1, 2) → D + 1, (0, 2) → D + 2.
        D + match (a, b) {
            (0, 1) => 0,
            (1, 2) => 1,
            _ => 2,
        }
    }
}

/// Difference step of the probes.
const EPS: f64 = 1e-7;

/// Measures every particle's tangent at the iterate saved by `linearise_at` into
/// `work.tangent` (the whole tangent) and `work.moduli` (isotropic moduli read from it).
pub(super) fn probe<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    dt: f64,
) where
    dyn Material: DimensionDispatch<D>,
{
    let n = sim.particles.len();
    let identity = Matrix::<D>::identity();
    let floor = shear_floor(work.fbar.is_some());
    let comps = components(D);
    let m = comps.len();
    work.moduli.resize(n, [0.0; 2]);
    work.tangent.resize(n, [0.0; 36]);
    let rate = !sim.particles.velocity_gradient.is_empty();
    // ε₀ held at the iterate's: each particle's own tangent, not the section's response to
    // all of them strained at once (that is `out_of_plane.rs`'s rank-one term).
    let strain = sim.stress_scratch.out_of_plane_strain();
    sim.stress_scratch
        .hold_out_of_plane_strain(strain, &sim.particles.groups);
    for (probe, &(j, l)) in comps.iter().enumerate() {
        let mut g = Matrix::<D>::zeros();
        g[(j, l)] = 1.0;
        g[(l, j)] = 1.0;
        for p in 0..n {
            let a = a_bar(work, p);
            sim.particles.deformation_gradient[p] = (a + g * EPS) * work.f_n[p];
            if rate {
                sim.particles.velocity_gradient[p] = (a - identity + g * EPS) / dt;
            }
        }
        work.restore_state(sim);
        update_stress(&mut sim.particles, dt, &mut sim.stress_scratch);
        // A shear probe strains (j, l) and (l, j) both: halve it per component.
        let share = if j == l { 1.0 } else { 0.5 };
        for p in 0..n {
            let d = (sim.particles.stress[p] - work.stress_cur[p]) / EPS;
            for (r, &(i, k)) in comps.iter().enumerate() {
                work.tangent[p][r * m + probe] = d[(i, k)] * share;
            }
        }
    }
    for p in 0..n {
        let t = &mut work.tangent[p];
        // The estimate must be symmetric for the Cholesky (the tangents of these laws
        // are, up to the differences).
        for r in 0..m {
            for c in r + 1..m {
                let mean = 0.5 * (t[r * m + c] + t[c * m + r]);
                t[r * m + c] = mean;
                t[c * m + r] = mean;
            }
        }
        // Dλ + 2μ: σ₀₀ under a unit dilatation; μ: the (0, 1) shear stiffness.
        work.moduli[p][0] = (0..D).map(|jj| t[jj]).sum();
        work.moduli[p][1] = t[voigt::<D>(0, 1) * m + voigt::<D>(0, 1)];
        // A shear stiffness of at least a small share of the volumetric one keeps the
        // estimate factorable where a law has next to none (a liquid).
        let [volumetric, measured] = work.moduli[p];
        let mu = measured.max(floor * volumetric.max(0.0));
        let lambda = ((volumetric - 2.0 * mu) / D as f64).max(-2.0 * mu / D as f64);
        work.moduli[p] = [lambda, mu];
        if mu > measured {
            // The same floor as a deviatoric shear stiffness added to the whole tangent.
            let extra = mu - measured;
            let t = &mut work.tangent[p];
            for (r, &(i, k)) in comps.iter().enumerate() {
                for (c, &(j, l)) in comps.iter().enumerate() {
                    let delta = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
                    t[r * m + c] += extra
                        * (delta(i, j) * delta(k, l) + delta(i, l) * delta(k, j)
                            - 2.0 / D as f64 * delta(i, k) * delta(j, l));
                }
            }
        }
    }
    // Back to the iterate (the material state is restored before every later update).
    sim.stress_scratch
        .hold_out_of_plane_strain(None, &sim.particles.groups);
    if work.zz_cur.len() == n {
        sim.particles.stress_zz.copy_from_slice(&work.zz_cur);
    }
    for p in 0..n {
        let a = a_bar(work, p);
        sim.particles.deformation_gradient[p] = a * work.f_n[p];
        sim.particles.stress[p] = work.stress_cur[p];
        if rate {
            sim.particles.velocity_gradient[p] = (a - identity) / dt;
        }
    }
}

/// The least shear stiffness the preconditioner's estimate gives a particle, as a share of
/// its volumetric stiffness Dλ + 2μ: 1% without F-bar; with F-bar the volumetric part acts
/// on patch means, so the estimate stays factorable with far less.
fn shear_floor(fbar: bool) -> f64 {
    if fbar { 1e-4 } else { 0.01 }
}

/// Adds particle `p`'s material stiffness with its whole tangent `t` (Voigt, [`components`]
/// order) to an element block: K_ab,ij += V Σ_kl ∇w_a,k C_ikjl ∇w_b,l, for the stencil
/// gradients `gradient`.
pub(super) fn add_anisotropic_block<const D: usize>(
    block: &mut [f64],
    gradient: &[crate::math::Vector<D>],
    t: &[f64; 36],
    volume: f64,
) {
    let stencil = gradient.len();
    let m = components(D).len();
    for (a, ga) in gradient.iter().enumerate() {
        // c[i][j][l] = Σ_k ∇w_a,k C_ikjl.
        let mut c = [[[0.0; 3]; 3]; 3];
        for (i, ci) in c.iter_mut().enumerate().take(D) {
            for (j, cij) in ci.iter_mut().enumerate().take(D) {
                for (l, cijl) in cij.iter_mut().enumerate().take(D) {
                    let col = voigt::<D>(j, l);
                    *cijl = (0..D).map(|k| ga[k] * t[voigt::<D>(i, k) * m + col]).sum();
                }
            }
        }
        for (b, gb) in gradient.iter().enumerate() {
            for i in 0..D {
                for j in 0..D {
                    let k: f64 = (0..D).map(|l| c[i][j][l] * gb[l]).sum();
                    block[((a * stencil + b) * D + i) * D + j] += volume * k;
                }
            }
        }
    }
}

/// The volumetric stiffness of a whole tangent `t` (Voigt, [`components`] order): the mean
/// stress a unit dilatation gives per unit volumetric strain, eᵀ t e / D² (e the normal
/// components); λ + 2μ/D for an isotropic tangent. F-bar puts it on the patch's mean
/// dilatation.
pub(super) fn volumetric_part<const D: usize>(t: &[f64; 36]) -> f64 {
    let m = components(D).len();
    let sum: f64 = (0..D).flat_map(|r| (0..D).map(move |c| t[r * m + c])).sum();
    sum / (D * D) as f64
}

/// The deviatoric part P t P of a whole tangent `t` (Voigt, [`components`] order; P = I −
/// e eᵀ/D takes the volumetric part out of a strain and of a stress): what F-bar leaves on
/// the particle's own strain. For an isotropic tangent, λ becomes −2μ/D.
pub(super) fn deviatoric_part<const D: usize>(t: &[f64; 36]) -> [f64; 36] {
    let m = components(D).len();
    let normal = |r: usize| if r < D { 1.0 } else { 0.0 };
    // Row and column means over the normal components, and the normal block's mean.
    let mut row_mean = [0.0; 6];
    let mut col_mean = [0.0; 6];
    for r in 0..m {
        for c in 0..D {
            row_mean[r] += t[r * m + c] / D as f64;
            col_mean[r] += t[c * m + r] / D as f64;
        }
    }
    let both: f64 = (0..D).map(|r| row_mean[r]).sum::<f64>() / D as f64;
    let mut out = [0.0; 36];
    for r in 0..m {
        for c in 0..m {
            out[r * m + c] = t[r * m + c] - row_mean[r] * normal(c) - normal(r) * col_mean[c]
                + normal(r) * normal(c) * both;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vector;

    #[test]
    fn voigt_indices_follow_the_component_order() {
        for (r, &(i, k)) in components(2).iter().enumerate() {
            assert_eq!((voigt::<2>(i, k), voigt::<2>(k, i)), (r, r));
        }
        for (r, &(i, k)) in components(3).iter().enumerate() {
            assert_eq!((voigt::<3>(i, k), voigt::<3>(k, i)), (r, r));
        }
    }

    /// An isotropic tangent in Voigt form gives the element block of the isotropic
    /// assembly, K_ab,ij = V (λ ∇w_a,i ∇w_b,j + μ ∇w_a,j ∇w_b,i + μ ∇w_a·∇w_b δ_ij).
    fn isotropic_block_matches<const D: usize>() {
        let (lambda, mu, volume) = (3.0, 2.0, 0.7);
        let comps = components(D);
        let m = comps.len();
        let delta = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
        let mut t = [0.0; 36];
        for (r, &(i, k)) in comps.iter().enumerate() {
            for (c, &(j, l)) in comps.iter().enumerate() {
                t[r * m + c] = lambda * delta(i, k) * delta(j, l)
                    + mu * (delta(i, j) * delta(k, l) + delta(i, l) * delta(k, j));
            }
        }
        let gradient: Vec<Vector<D>> = (0..4)
            .map(|a| Vector::<D>::from_fn(|d, _| (a * 3 + d) as f64 * 0.37 - 1.1))
            .collect();
        let stencil = gradient.len();
        let mut block = vec![0.0; stencil * stencil * D * D];
        add_anisotropic_block(&mut block, &gradient, &t, volume);
        for (a, ga) in gradient.iter().enumerate() {
            for (b, gb) in gradient.iter().enumerate() {
                for i in 0..D {
                    for j in 0..D {
                        let expected = volume
                            * (lambda * ga[i] * gb[j]
                                + mu * ga[j] * gb[i]
                                + mu * ga.dot(gb) * delta(i, j));
                        let got = block[((a * stencil + b) * D + i) * D + j];
                        assert!((got - expected).abs() < 1e-12, "{a} {b} {i} {j}");
                    }
                }
            }
        }
    }

    #[test]
    fn an_isotropic_tangent_gives_the_isotropic_block() {
        isotropic_block_matches::<2>();
        isotropic_block_matches::<3>();
    }

    /// F-bar's split of an isotropic tangent: λ + 2μ/D on the patch, and the particle's
    /// part the isotropic one with λ = −2μ/D; the deviatoric part of any tangent gives no
    /// stress for a dilatation and no mean stress for any strain.
    fn split_matches<const D: usize>() {
        let (lambda, mu) = (3.0, 2.0);
        let comps = components(D);
        let m = comps.len();
        let delta = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
        let isotropic = |lambda: f64| {
            let mut t = [0.0; 36];
            for (r, &(i, k)) in comps.iter().enumerate() {
                for (c, &(j, l)) in comps.iter().enumerate() {
                    t[r * m + c] = lambda * delta(i, k) * delta(j, l)
                        + mu * (delta(i, j) * delta(k, l) + delta(i, l) * delta(k, j));
                }
            }
            t
        };
        let t = isotropic(lambda);
        let kappa = volumetric_part::<D>(&t);
        assert!(
            (kappa - (lambda + 2.0 * mu / D as f64)).abs() < 1e-12,
            "{kappa}"
        );
        let expected = isotropic(-2.0 * mu / D as f64);
        let got = deviatoric_part::<D>(&t);
        for r in 0..m * m {
            assert!((got[r] - expected[r]).abs() < 1e-12, "{r}: {got:?}");
        }
        // An anisotropic, non-symmetric tangent.
        let mut t = [0.0; 36];
        for (r, value) in t.iter_mut().enumerate().take(m * m) {
            *value = 1.0 + (r * 7 % 11) as f64 * 0.3;
        }
        let dev = deviatoric_part::<D>(&t);
        for r in 0..m {
            let dilatation: f64 = (0..D).map(|c| dev[r * m + c]).sum();
            let mean: f64 = (0..D).map(|c| dev[c * m + r]).sum();
            assert!(dilatation.abs() < 1e-12 && mean.abs() < 1e-12, "{r}");
        }
    }

    #[test]
    fn the_fbar_split_keeps_the_deviatoric_part_on_the_particle() {
        split_matches::<2>();
        split_matches::<3>();
    }
}
