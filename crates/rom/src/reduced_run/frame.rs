//! Frame output: the map evaluated at every particle of the scene, the output fields
//! staged in the result layout of a full run, and the frame's diagnostics.

use super::setup::Reduced;
use super::stress::{matrix_from_rows, update_stress_parallel};
use crate::RomError;
use mpm_core::kernels::Kernel;
use mpm_core::material::{BatchStats, Material};
use mpm_core::math::{Vector, determinant, vector_from_slice};
use mpm_core::output::{FRAME_DIAGNOSTICS, Frame, OutputSink};
use mpm_core::solver::DimensionDispatch;

impl<const D: usize, K: Kernel> Reduced<'_, D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Evaluates the map at every particle and fills the output buffers; returns the
    /// frame's diagnostics.
    fn evaluate_frame(&mut self, dt: f64, steps: u64) -> Result<[f64; 14], RomError> {
        let n = self.all.len();
        self.map.positions(&self.q, &self.all, &mut self.all_x)?;
        self.map
            .velocities(&self.q, &self.q_rate, &self.all, &mut self.all_flat_v)?;
        self.map
            .gradients(&self.q, &self.all, &mut self.all_flat_f)?;
        let particles = &self.sim.particles;
        let (mut kinetic, mut gravity_energy, mut max_speed) = (0.0, 0.0, 0.0f64);
        let mut momentum = Vector::<D>::zeros();
        let mut min_det = f64::INFINITY;
        for p in 0..n {
            let v: Vector<D> = vector_from_slice(&self.all_flat_v[p * D..]);
            let x: Vector<D> = vector_from_slice(&self.all_x[p * D..]);
            let m = particles.mass[p];
            kinetic += 0.5 * m * v.norm_squared();
            gravity_energy -= m * self.settings.gravity.dot(&x);
            max_speed = max_speed.max(v.norm());
            momentum += v * m;
            self.all_v[p] = v;
            self.all_f[p] = matrix_from_rows::<D>(&self.all_flat_f[p * D * D..]);
            min_det = min_det.min(determinant(&self.all_f[p]));
        }
        let mut strain = BatchStats::default();
        for group in &particles.groups {
            let r = group.range.clone();
            strain = strain.merge(update_stress_parallel::<D>(
                &*group.material,
                dt.max(0.0),
                &self.all_f[r.clone()],
                &particles.volume0[r.clone()],
                &mut self.all_stress[r],
            ));
        }
        self.frame_strain = strain.strain_energy;
        if self.stats.max_wave_speed == 0.0 {
            self.stats.max_wave_speed = strain.max_wave_speed;
        }
        for (field, out) in self.fields.iter().zip(self.staging.iter_mut()) {
            let c = field.components();
            for p in 0..n {
                let o = particles.id[p] as usize * c;
                match field.name.as_str() {
                    "x" => out[o..o + D].copy_from_slice(&self.all_x[p * D..(p + 1) * D]),
                    "v" => out[o..o + D].copy_from_slice(self.all_v[p].as_slice()),
                    "F" | "stress" => {
                        let m = if field.name == "F" {
                            &self.all_f[p]
                        } else {
                            &self.all_stress[p]
                        };
                        for r in 0..D {
                            for col in 0..D {
                                out[o + r * D + col] = m[(r, col)];
                            }
                        }
                    }
                    "J" => out[o] = determinant(&self.all_f[p]),
                    "volume" => out[o] = determinant(&self.all_f[p]) * particles.volume0[p],
                    "mass" => out[o] = particles.mass[p],
                    _ => {}
                }
            }
            if field.name == "material" {
                for (g, group) in particles.groups.iter().enumerate() {
                    for p in group.range.clone() {
                        out[particles.id[p] as usize] = g as f64;
                    }
                }
            }
        }
        let total = kinetic + strain.strain_energy + gravity_energy;
        Ok([
            steps as f64,
            dt,
            kinetic,
            strain.strain_energy,
            gravity_energy,
            total,
            max_speed,
            min_det,
            momentum.norm(),
            // The reduced run keeps no energy ledger and no conservation totals: no
            // boundary work, nothing booked as dissipated, no energy error or angular
            // momentum measured, no surface energy (solids only).
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ])
    }

    /// Evaluates the frame and writes it to `sink`; returns its diagnostics.
    pub(super) fn write_frame(
        &mut self,
        sink: &mut dyn OutputSink,
        index: usize,
        time: f64,
        dt: f64,
        steps: u64,
    ) -> Result<[f64; 14], RomError> {
        let diagnostics = self.evaluate_frame(dt, steps)?;
        debug_assert_eq!(diagnostics.len(), FRAME_DIAGNOSTICS.len());
        sink.write_frame(&Frame {
            index,
            time,
            values: &self.staging,
            diagnostics: &diagnostics,
        })?;
        Ok(diagnostics)
    }
}
