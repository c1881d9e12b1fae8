//! Particle fields copied into output (id) order for the result writer.

use crate::math::determinant;
use crate::output::FieldInfo;
use crate::particles::Particles;

/// The output fields with their per-particle shapes, in the scene's order.
pub(super) fn output_fields<const D: usize>(
    names: &[String],
    particles: &Particles<D>,
) -> Vec<FieldInfo> {
    names
        .iter()
        .map(|name| {
            let shape = match name.as_str() {
                "x" | "v" => vec![D],
                "stress" | "F" => vec![D, D],
                "J" | "mass" | "volume" | "material" | crate::scene::STRESS_ZZ => vec![],
                other if particles.shared.contains(other) => vec![],
                other => {
                    let comps = particles
                        .groups
                        .iter()
                        .flat_map(|g| g.material.state_fields().iter())
                        .find(|s| s.name == other)
                        .map_or(1, |s| s.components);
                    if comps == 1 { vec![] } else { vec![comps] }
                }
            };
            FieldInfo {
                name: name.clone(),
                shape,
            }
        })
        .collect()
}

/// Copies particle fields into the staging buffers in output (id) order.
pub(super) fn fill_staging<const D: usize>(
    p: &Particles<D>,
    fields: &[FieldInfo],
    staging: &mut [Vec<f64>],
) {
    for (field, out) in fields.iter().zip(staging.iter_mut()) {
        let c = field.components();
        match field.name.as_str() {
            "x" | "v" => {
                let src = if field.name == "x" {
                    &p.position
                } else {
                    &p.velocity
                };
                for (i, v) in src.iter().enumerate() {
                    let o = p.id[i] as usize * c;
                    out[o..o + D].copy_from_slice(v.as_slice());
                }
            }
            "stress" | "F" => {
                let src = if field.name == "F" {
                    &p.deformation_gradient
                } else {
                    &p.stress
                };
                for (i, m) in src.iter().enumerate() {
                    let o = p.id[i] as usize * c;
                    // Row-major [row, column] as numpy expects.
                    for r in 0..D {
                        for col in 0..D {
                            out[o + r * D + col] = m[(r, col)];
                        }
                    }
                }
            }
            "J" | "volume" => {
                for (i, f) in p.deformation_gradient.iter().enumerate() {
                    let j = determinant(f);
                    out[p.id[i] as usize] = if field.name == "J" {
                        j
                    } else {
                        j * p.volume0[i]
                    };
                }
            }
            crate::scene::STRESS_ZZ => {
                for (i, zz) in p.stress_zz.iter().enumerate() {
                    out[p.id[i] as usize] = *zz;
                }
            }
            "mass" => {
                for (i, m) in p.mass.iter().enumerate() {
                    out[p.id[i] as usize] = *m;
                }
            }
            "material" => {
                for (g, group) in p.groups.iter().enumerate() {
                    for i in group.range.clone() {
                        out[p.id[i] as usize] = g as f64;
                    }
                }
            }
            name if p.shared.contains(name) => {
                let values = p.shared.get(name).unwrap_or(&[]);
                for (i, v) in values.iter().enumerate() {
                    out[p.id[i] as usize] = *v;
                }
            }
            name => {
                for group in &p.groups {
                    let specs = group.material.state_fields();
                    let position = specs.iter().position(|s| s.name == name);
                    for (k, i) in group.range.clone().enumerate() {
                        let o = p.id[i] as usize * c;
                        match position {
                            Some(f) => {
                                out[o..o + c].copy_from_slice(&group.state[f][k * c..(k + 1) * c])
                            }
                            None => out[o..o + c].fill(0.0),
                        }
                    }
                }
            }
        }
    }
}
