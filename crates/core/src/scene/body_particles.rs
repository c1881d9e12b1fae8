//! Turning bodies into particles: each body's shape filled on its lattice (only where
//! particles may lie), holes cut, the part outside the domain clipped or refused, initial
//! velocities set; particle files (CSV, result stores) read.

use super::budget::{self, Limits};
use super::lattice::{self, Region};
use super::validator::Validator;
use super::{InitialVelocity, ParticleFileFormat, Scene, Shape};
use crate::plugin::Registry;
use std::path::{Path, PathBuf};

/// Particles generated for one body, dimension-erased (`dimension` numbers per particle).
#[derive(Clone, Debug, Default)]
pub struct BodyParticles {
    /// Index of the body in `scene.bodies`.
    pub body: usize,
    /// Positions, `dimension` numbers per particle.
    pub positions: Vec<f64>,
    /// Volume of each particle.
    pub volumes: Vec<f64>,
    /// Initial velocities, `dimension` numbers per particle.
    pub velocities: Vec<f64>,
    /// Particle spacing (for the GIMP particle size), metres.
    pub spacing: f64,
}

impl Validator {
    pub(super) fn generate_bodies(
        &mut self,
        s: &Scene,
        registry: &Registry,
        base_dir: &Path,
    ) -> Vec<BodyParticles> {
        let dim = self.dim;
        let dx = s.domain.cell_size;
        let mut out = Vec::new();
        let mut domain = Region {
            lo: [0.0; 3],
            hi: [0.0; 3],
        };
        domain.lo[..dim].copy_from_slice(&s.domain.min);
        domain.hi[..dim].copy_from_slice(&s.domain.max);
        for (i, b) in s.bodies.iter().enumerate() {
            let path = format!("bodies[{i}]");
            let h = dx / b.particles_per_cell as f64;
            let mut body = BodyParticles {
                body: i,
                spacing: h,
                ..Default::default()
            };
            // Only the lattice points where particles may lie are visited (`budget`).
            let region = budget::body_region(&domain, dx, b.clip_to_domain);
            // With refined levels a round shape is first filled out to `grow` past its
            // surface: a particle just outside it may have children (split below) inside it,
            // as a uniform run at the level's cell has particles there. The children and
            // particles outside the shape are dropped after the split.
            let grow = if s.solver.refinement.is_some() {
                0.5 * h * (dim as f64).sqrt()
            } else {
                0.0
            };
            let bounds = lattice::bounding_box(dim, &b.shape).map(|mut r| {
                for a in 0..dim {
                    r.lo[a] -= grow;
                    r.hi[a] += grow;
                }
                r.intersect(&region)
            });
            let bounds = bounds.unwrap_or(region);
            let filled = match &b.shape {
                Shape::Box { min, max } => lattice::fill_box(dim, min, max, h, &region, &mut body),
                Shape::Sphere { center, radius } => lattice::fill_lattice(
                    dim,
                    center,
                    *radius + grow,
                    h,
                    [0.5; 3],
                    &bounds,
                    &mut body,
                    |r| r.iter().map(|x| x * x).sum::<f64>() <= (radius + grow).powi(2),
                ),
                Shape::Cylinder {
                    center,
                    radius,
                    axis,
                    length,
                } => {
                    let norm = axis.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let a: Vec<f64> = axis.iter().map(|x| x / norm).collect();
                    let reach = (radius * radius + length * length / 4.0).sqrt() + grow;
                    // Along a coordinate axis, fit the layers to the length exactly: an odd
                    // number of layers puts one on the centre, an even number straddles it.
                    let mut offset = [0.5; 3];
                    if let Some(k) = a.iter().position(|x| (x.abs() - 1.0).abs() < 1e-12) {
                        let layers = (length / h).round() as i64;
                        if layers % 2 == 1 && ((layers as f64) * h - length).abs() < 1e-9 * length {
                            offset[k] = 0.0;
                        }
                    }
                    lattice::fill_lattice(dim, center, reach, h, offset, &bounds, &mut body, |r| {
                        let along: f64 = r.iter().zip(&a).map(|(x, y)| x * y).sum();
                        let r2: f64 = r.iter().map(|x| x * x).sum::<f64>() - along * along;
                        along.abs() <= length / 2.0 + grow && r2 <= (radius + grow).powi(2)
                    })
                }
                Shape::File { path: file, format } => {
                    let full: PathBuf = base_dir.join(file);
                    let loaded = match format {
                        ParticleFileFormat::Csv => read_csv_particles(&full, dim, h),
                        ParticleFileFormat::Zarr => registry.read_particle_store(&full, dim, h),
                    };
                    match loaded {
                        Ok((positions, volumes)) => {
                            body.positions = positions;
                            body.volumes = volumes;
                            Ok(())
                        }
                        Err(message) => {
                            self.err(format!("{path}.shape.file.path"), message);
                            continue;
                        }
                    }
                }
                Shape::Inflow(inflow) => {
                    // Every particle waits at the inlet without volume (so without mass)
                    // until its layer enters (`solver/inflow.rs`).
                    body.positions = inflow.positions(dim, h, s.solver.end_time);
                    body.volumes = vec![0.0; body.positions.len() / dim];
                    Ok(())
                }
            };
            if let Err(message) = filled {
                self.err(format!("{path}.shape"), message);
                continue;
            }
            // Split before the holes are cut and keep only the particles inside the shape,
            // so that a refined level outlines the shape and its holes at its own spacing,
            // as a uniform run at that cell would (a child lies where that run's particle
            // does).
            if let Some(refinement) = &s.solver.refinement {
                if let Err(message) = super::refinement::split_for_refinement(
                    dim,
                    refinement,
                    &s.domain,
                    &mut body,
                    self.max_particles,
                ) {
                    self.err("solver.refinement", message);
                    continue;
                }
                // (`grow` > 0 here: even unsplit particles may lie past the shape.)
                if !matches!(b.shape, Shape::File { .. }) {
                    let keep: Vec<bool> = body
                        .positions
                        .chunks_exact(dim)
                        .map(|x| shape_contains(&b.shape, x))
                        .collect();
                    retain_particles(&mut body, dim, &keep);
                }
            }
            for (h_index, hole) in b.holes.iter().enumerate() {
                if matches!(hole, Shape::File { .. } | Shape::Inflow(_)) {
                    self.err(
                        format!("{path}.holes[{h_index}]"),
                        "a hole is a box, sphere or cylinder",
                    );
                    continue;
                }
                let keep: Vec<bool> = body
                    .positions
                    .chunks_exact(dim)
                    .map(|x| !shape_contains(hole, x))
                    .collect();
                retain_particles(&mut body, dim, &keep);
            }
            if b.clip_to_domain {
                let keep: Vec<bool> = body
                    .positions
                    .chunks_exact(dim)
                    .map(|x| (0..dim).all(|a| x[a] >= s.domain.min[a] && x[a] <= s.domain.max[a]))
                    .collect();
                retain_particles(&mut body, dim, &keep);
            }
            let n = body.volumes.len();
            if n == 0 {
                self.err(
                    format!("{path}.shape"),
                    "the shape holds zero particles (it is smaller than the particle spacing)",
                );
                continue;
            }
            // Every particle must lie in the domain (the grid is padded beyond it so every
            // kernel's stencil fits).
            let mut outside = None;
            for p in 0..n {
                for a in 0..dim {
                    let x = body.positions[p * dim + a];
                    if !(x >= s.domain.min[a] && x <= s.domain.max[a]) {
                        outside = Some((p, a, x));
                        break;
                    }
                }
                if outside.is_some() {
                    break;
                }
            }
            if let Some((p, a, x)) = outside {
                self.err(
                    format!("{path}.shape"),
                    format!(
                        "particle {p} lies at {x} on axis {a}, outside the domain [{}, {}]",
                        s.domain.min[a], s.domain.max[a]
                    ),
                );
                continue;
            }
            body.velocities = initial_velocities(dim, &body.positions, b.velocity.as_ref());
            out.push(body);
        }
        out
    }
}

/// Keeps the particles whose `keep` entry is true.
fn retain_particles(body: &mut BodyParticles, dim: usize, keep: &[bool]) {
    let mut k = 0;
    body.positions.retain(|_| {
        let inside = keep[k / dim];
        k += 1;
        inside
    });
    let mut k = 0;
    body.volumes.retain(|_| {
        let inside = keep[k];
        k += 1;
        inside
    });
}

impl Shape {
    /// Whether point `x` lies in this box, sphere or cylinder (never in a file shape).
    pub(crate) fn contains(&self, x: &[f64]) -> bool {
        shape_contains(self, x)
    }
}

/// Whether point `x` lies in a box, sphere or cylinder (never in a file shape).
fn shape_contains(shape: &Shape, x: &[f64]) -> bool {
    match shape {
        Shape::Box { min, max } => x
            .iter()
            .enumerate()
            .all(|(a, v)| *v >= min[a] && *v <= max[a]),
        Shape::Sphere { center, radius } => {
            x.iter()
                .zip(center)
                .map(|(a, c)| (a - c).powi(2))
                .sum::<f64>()
                <= radius * radius
        }
        Shape::Cylinder {
            center,
            radius,
            axis,
            length,
        } => {
            let norm = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
            let r = x.iter().zip(center).map(|(a, c)| a - c);
            let along: f64 = r.clone().zip(axis).map(|(a, b)| a * b / norm).sum();
            let r2: f64 = r.map(|a| a * a).sum::<f64>() - along * along;
            along.abs() <= length / 2.0 && r2 <= radius * radius
        }
        Shape::File { .. } | Shape::Inflow(_) => false,
    }
}

fn initial_velocities(dim: usize, positions: &[f64], spec: Option<&InitialVelocity>) -> Vec<f64> {
    let n = positions.len() / dim;
    let mut v = vec![0.0; n * dim];
    for p in 0..n {
        let x = &positions[p * dim..(p + 1) * dim];
        let out = &mut v[p * dim..(p + 1) * dim];
        match spec {
            None => {}
            Some(InitialVelocity::Uniform(u)) => out.copy_from_slice(u),
            Some(InitialVelocity::BarMode {
                amplitude,
                axis,
                fixed_end,
                length,
            }) => {
                let s = x[*axis] - fixed_end;
                out[*axis] = amplitude * (std::f64::consts::PI * s / (2.0 * length)).sin();
            }
            Some(InitialVelocity::Rotation {
                center,
                angular_velocity,
            }) => {
                let r: Vec<f64> = (0..dim).map(|a| x[a] - center[a]).collect();
                if dim == 2 {
                    let w = angular_velocity[0];
                    out[0] = -w * r[1];
                    out[1] = w * r[0];
                } else {
                    let w = angular_velocity;
                    out[0] = w[1] * r[2] - w[2] * r[1];
                    out[1] = w[2] * r[0] - w[0] * r[2];
                    out[2] = w[0] * r[1] - w[1] * r[0];
                }
            }
            Some(InitialVelocity::Affine { center, gradient }) => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = (0..dim)
                        .map(|j| gradient[i * dim + j] * (x[j] - center[j]))
                        .sum();
                }
            }
        }
    }
    v
}

/// Reads particles from CSV: a header naming columns `x`, `y` (and `z` in 3D), optionally
/// `volume`; without it each particle gets `spacing^dim`.
pub fn read_csv_particles(
    path: &Path,
    dim: usize,
    spacing: f64,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let limits = Limits::current();
    let size = std::fs::metadata(path)
        .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?
        .len();
    if size > limits.max_file_bytes {
        return Err(format!(
            "`{}` has {size} bytes; at most {} are read (limit `file_bytes`)",
            path.display(),
            limits.max_file_bytes
        ));
    }
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?;
    let rows = text.lines().filter(|l| !l.trim().is_empty()).count();
    if rows.saturating_sub(1) as u64 > limits.max_particles {
        return Err(format!(
            "`{}` holds {} particles; at most {} are allowed (limit `particles`)",
            path.display(),
            rows - 1,
            limits.max_particles
        ));
    }
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Err(format!("`{}` is empty", path.display()));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |name: &str| cols.iter().position(|c| *c == name);
    let names = ["x", "y", "z"];
    let mut idx = Vec::new();
    for name in names.iter().take(dim) {
        idx.push(
            find(name).ok_or_else(|| {
                format!("`{}`: the header has no `{name}` column", path.display())
            })?,
        );
    }
    let vol_col = find("volume");
    let default_volume = spacing.powi(dim as i32);
    let (mut pos, mut vol) = (Vec::new(), Vec::new());
    for (line_no, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let get = |c: usize| -> Result<f64, String> {
            let s = fields.get(c).ok_or_else(|| {
                format!(
                    "`{}` line {}: missing column {}",
                    path.display(),
                    line_no + 1,
                    c + 1
                )
            })?;
            let x: f64 = s.parse().map_err(|_| {
                format!(
                    "`{}` line {}: `{s}` is not a number",
                    path.display(),
                    line_no + 1
                )
            })?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(format!(
                    "`{}` line {}: non-finite number",
                    path.display(),
                    line_no + 1
                ))
            }
        };
        for &c in &idx {
            pos.push(get(c)?);
        }
        let v = match vol_col {
            Some(c) => get(c)?,
            None => default_volume,
        };
        if v <= 0.0 {
            return Err(format!(
                "`{}` line {}: volume must be > 0",
                path.display(),
                line_no + 1
            ));
        }
        vol.push(v);
    }
    Ok((pos, vol))
}
