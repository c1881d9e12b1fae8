//! Saving a simulation's whole state into a [`Checkpoint`] and restoring it, so a resumed
//! run continues bit for bit: particles with every field (in their current, reordered
//! order), material and physics state, the clock, statistics the next step reads, the
//! energy ledger, the reference's running error, the physics report, contact and the
//! mode's own state.

use super::DimensionDispatch;
use super::simulation::Simulation;
use crate::checkpoint::{Checkpoint, CheckpointError, Scalars};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector};

/// Flattens vectors or matrices (nalgebra's column-major storage) into numbers.
fn flatten<T: AsRef<[f64]>>(values: &[T]) -> Vec<f64> {
    values
        .iter()
        .flat_map(|v| v.as_ref().iter().copied())
        .collect()
}

fn vectors<const D: usize>(numbers: &[f64]) -> Vec<Vector<D>> {
    numbers
        .chunks_exact(D)
        .map(Vector::<D>::from_column_slice)
        .collect()
}

fn matrices<const D: usize>(numbers: &[f64]) -> Vec<Matrix<D>> {
    numbers
        .chunks_exact(D * D)
        .map(Matrix::<D>::from_column_slice)
        .collect()
}

/// Copies the checkpoint's array `name` into `target`, which keeps its length (0 when the
/// run does not allocate the field).
fn restore_vec<T>(
    c: &Checkpoint,
    name: &str,
    target: &mut Vec<T>,
    per_item: usize,
    build: impl Fn(&[f64]) -> Vec<T>,
    strict: bool,
) -> Result<(), CheckpointError> {
    match c.get(name, target.len() * per_item) {
        Ok(numbers) => *target = build(numbers),
        // A stage that allocates a field the stage before did not keeps its own start
        // value (an APIC matrix of zeros, say).
        Err(_) if !strict => {}
        Err(e) => return Err(e),
    }
    Ok(())
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Writes the simulation's state into `c`. The mode drops the caches it would rebuild
    /// after a resume, so the run goes on as a resumed one does.
    pub(super) fn save_state(&mut self, c: &mut Checkpoint) {
        let p = &self.particles;
        c.put("particles.position", flatten(&p.position));
        c.put("particles.velocity", flatten(&p.velocity));
        c.put("particles.mass", p.mass.clone());
        c.put("particles.volume0", p.volume0.clone());
        c.put(
            "particles.deformation_gradient",
            flatten(&p.deformation_gradient),
        );
        c.put("particles.stress", flatten(&p.stress));
        c.put("particles.stress_zz", p.stress_zz.clone());
        c.put("particles.affine", flatten(&p.affine));
        c.put("particles.velocity_gradient", flatten(&p.velocity_gradient));
        c.put("particles.half_size", p.half_size.clone());
        c.put("particles.initial_position", flatten(&p.initial_position));
        c.put("particles.external_force", flatten(&p.external_force));
        c.put("particles.id", p.id.iter().map(|&i| i as f64).collect());
        c.put(
            "particles.contact_field",
            p.contact_field.iter().map(|&f| f as f64).collect(),
        );
        for (g, group) in p.groups.iter().enumerate() {
            for (j, values) in group.state.iter().enumerate() {
                c.put(format!("group.{g}.state.{j}"), values.clone());
            }
        }
        for name in p.shared.names() {
            let values = p.shared.get(name).unwrap_or(&[]).to_vec();
            c.put(format!("shared.{name}"), values);
        }
        let mut s = Scalars::new();
        let relax = self.relax_time.unwrap_or(f64::NAN);
        s.push(&[
            self.time,
            self.steps as f64,
            self.sort_counter as f64,
            self.energy0,
            self.physics_dt,
            relax,
        ]);
        s.push(&self.ledger.to_array());
        c.put("ledger.openings", vec![self.ledger.openings]);
        c.put("ledger.viscous", vec![self.ledger.viscous]);
        c.put("ledger.volume_source", vec![self.ledger.volume_source]);
        c.put("simulation.surface_energy", vec![self.surface_energy]);
        let k = &self.kinematics;
        s.push(&[k.kinetic_energy]);
        s.push(k.momentum.as_slice());
        s.push(&[
            k.gravity_energy,
            k.max_speed,
            k.min_det_f,
            k.min_det_particle as f64,
        ]);
        let st = &self.stresses;
        s.push(&[
            st.batch.strain_energy,
            st.batch.max_wave_speed,
            st.free_strain_work,
            st.plastic_work,
        ]);
        c.put("simulation.scalars", s.into_vec());
        c.set_state("step", self.steps.into());
        c.set_state("time", self.time.into());
        let off = self.settings.mechanics == crate::scene::Mechanics::Off;
        c.set_state("mechanics_off", off.into());
        if let Some(r) = &self.reference {
            c.set_state("reference", r.save_state());
        }
        c.set_state(
            "report",
            serde_json::json!({
                "maxima": self.report.maxima,
                "tables": self.report.tables,
            }),
        );
        self.stress_scratch.save(c);
        if let Some(contact) = &self.contact {
            contact.save(c);
        }
        if let Some(inflow) = &self.inflow {
            inflow.save(c);
        }
        if let Some(mode) = &mut self.mode {
            mode.save(c);
        }
    }

    /// Restores what [`Simulation::save_state`] wrote into a simulation freshly built from
    /// the same scene (not initialised).
    pub(super) fn restore_state(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        self.restore_particles(c, true)?;
        let mut s = self.restore_clock(c)?;
        let [energy0, physics_dt, relax] = s.take_n()?;
        self.energy0 = energy0;
        self.physics_dt = physics_dt;
        self.relax_time = (!relax.is_nan()).then_some(relax);
        self.ledger = crate::energy_ledger::EnergyLedger::from_array(s.take_n()?);
        // Absent from checkpoints written before inlets existed.
        self.ledger.openings = c.get("ledger.openings", 1).map_or(0.0, |v| v[0]);
        // Absent from checkpoints written before the viscous dissipation was booked.
        self.ledger.viscous = c.get("ledger.viscous", 1).map_or(0.0, |v| v[0]);
        // Absent from checkpoints written before the volume source's work was booked.
        self.ledger.volume_source = c.get("ledger.volume_source", 1).map_or(0.0, |v| v[0]);
        self.surface_energy = c.get("simulation.surface_energy", 1).map_or(0.0, |v| v[0]);
        self.restore_statistics(&mut s)?;
        self.stress_scratch.restore(c)?;
        // The physics operators' stencils and scratch rows at the restored positions (the
        // next step builds them again where particles moved; a resume with no step left
        // reports the same node arrays as the run that wrote the checkpoint).
        if self.needs_interpolation {
            self.build_physics_stencils();
        }
        if let Some(r) = &mut self.reference {
            r.restore_state(c.state("reference").clone())
                .map_err(|e| CheckpointError::Invalid(format!("reference: {e}")))?;
        }
        let report = c.state("report");
        self.report.maxima = serde_json::from_value(report["maxima"].clone())
            .map_err(|e| CheckpointError::Invalid(format!("report.maxima: {e}")))?;
        self.report.tables = serde_json::from_value(report["tables"].clone())
            .map_err(|e| CheckpointError::Invalid(format!("report.tables: {e}")))?;
        if let Some(contact) = &mut self.contact {
            contact.restore(c)?;
        }
        if let Some(inflow) = &mut self.inflow {
            inflow.restore(c, true)?;
        }
        if let Some(mode) = &mut self.mode {
            mode.restore(c)?;
        }
        Ok(())
    }

    /// Takes over the state the stage before left (`c`, saved at its end) into this
    /// stage's freshly built simulation: the particles with the fields both stages have,
    /// the clock, the last step's statistics, the stress update's applied free strain and
    /// contact; a physics operator whose fields the stage before did not have is
    /// initialised, and the energy balance, reference, report and mode start afresh.
    pub(super) fn take_over(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        let carried = self.restore_particles(c, false)?;
        let mut s = self.restore_clock(c)?;
        // The energy balance and the physics step bound start afresh.
        let _: [f64; 3 + 6] = s.take_n()?;
        self.restore_statistics(&mut s)?;
        self.stress_scratch.restore(c)?;
        if let Some(contact) = &mut self.contact {
            contact.restore(c)?;
        }
        // A pressure inlet goes on from where its reservoir stood.
        if let Some(inflow) = &mut self.inflow {
            inflow.restore(c, false)?;
        }
        // Physics operators: those whose every field was carried over continue; the others
        // set their fields' initial values.
        if !self.physics.is_empty() {
            if self.needs_interpolation {
                self.build_physics_stencils();
            }
            let fresh: Vec<bool> = self
                .physics
                .iter()
                .map(|slot| {
                    slot.physics
                        .fields()
                        .iter()
                        .any(|f| !carried.contains(&f.name))
                })
                .collect();
            let mut index = 0;
            self.each_physics(0.0, self.time, |physics, ctx| {
                if fresh[index] {
                    <dyn Material as DimensionDispatch<D>>::physics_stage(
                        physics,
                        crate::physics::Stage::Initialise,
                        ctx,
                    );
                }
                index += 1;
            });
            for stage in [
                crate::physics::Stage::Prepare,
                crate::physics::Stage::Finish,
            ] {
                self.physics_stage(stage, 0.0);
            }
            self.physics_dt = self.compute_physics_dt();
        }
        // A stage before without mechanics never updated the stress: the free strain its
        // physics applied (thermal expansion, cure shrinkage) is not in it yet. Take the
        // stress of the state handed over, as a run's start does.
        // Particles converted to another material at this hand-over start from F = I and
        // zero stress: their stress (and each group's wave speed) is computed the same way.
        let converted = c.state(super::conversion::CONVERTED).as_bool() == Some(true);
        if c.state("mechanics_off").as_bool() == Some(true) || converted {
            self.update_stresses(0.0);
        }
        if let Some(mut mode) = self.mode.take() {
            mode.take_over(self, c);
            self.mode = Some(mode);
        }
        self.ledger = crate::energy_ledger::EnergyLedger::default();
        self.kinematics = super::grid_to_particle::measure(&self.particles, self.settings.gravity);
        self.measure_stored_energy();
        self.energy0 = self.total_energy();
        Ok(())
    }

    /// The clock, step and reorder counters; returns the simulation's scalars after them.
    fn restore_clock(&mut self, c: &Checkpoint) -> Result<Scalars, CheckpointError> {
        let mut s = c.scalars("simulation.scalars")?;
        let [time, steps, sort_counter] = s.take_n()?;
        self.time = time;
        self.steps = steps as u64;
        self.sort_counter = sort_counter as u64;
        Ok(s)
    }

    /// The kinematic and stress statistics of the last step (the next step's bound reads
    /// them).
    fn restore_statistics(&mut self, s: &mut Scalars) -> Result<(), CheckpointError> {
        let k = &mut self.kinematics;
        k.kinetic_energy = s.take()?;
        k.momentum = Vector::<D>::from_column_slice(&s.take_n::<D>()?);
        let [gravity, max_speed, min_det_f, min_det_particle] = s.take_n()?;
        k.gravity_energy = gravity;
        k.max_speed = max_speed;
        k.min_det_f = min_det_f;
        k.min_det_particle = min_det_particle as usize;
        let st = &mut self.stresses;
        let [strain, wave, free_work, plastic_work] = s.take_n()?;
        st.batch.strain_energy = strain;
        st.batch.max_wave_speed = wave;
        st.free_strain_work = free_work;
        st.plastic_work = plastic_work;
        Ok(())
    }

    /// Restores the particles; `strict`: every field this run allocates must be there
    /// (a resume), else fields the checkpoint lacks keep their start values (a stage).
    /// Returns the shared physics fields taken from the checkpoint.
    fn restore_particles(
        &mut self,
        c: &Checkpoint,
        strict: bool,
    ) -> Result<Vec<&'static str>, CheckpointError> {
        let n = self.particles.len();
        let p = &mut self.particles;
        let by_vector = |x: &[f64]| vectors::<D>(x);
        let by_matrix = |x: &[f64]| matrices::<D>(x);
        let by_number = |x: &[f64]| x.to_vec();
        restore_vec(
            c,
            "particles.position",
            &mut p.position,
            D,
            by_vector,
            strict,
        )?;
        restore_vec(
            c,
            "particles.velocity",
            &mut p.velocity,
            D,
            by_vector,
            strict,
        )?;
        restore_vec(c, "particles.mass", &mut p.mass, 1, by_number, strict)?;
        restore_vec(c, "particles.volume0", &mut p.volume0, 1, by_number, strict)?;
        let dd = D * D;
        restore_vec(
            c,
            "particles.deformation_gradient",
            &mut p.deformation_gradient,
            dd,
            by_matrix,
            strict,
        )?;
        restore_vec(c, "particles.stress", &mut p.stress, dd, by_matrix, strict)?;
        // Written by every stress update and read by nothing in the step: a checkpoint from
        // before σzz was kept resumes with zeros until the first update.
        restore_vec(
            c,
            "particles.stress_zz",
            &mut p.stress_zz,
            1,
            by_number,
            false,
        )?;
        restore_vec(c, "particles.affine", &mut p.affine, dd, by_matrix, strict)?;
        restore_vec(
            c,
            "particles.velocity_gradient",
            &mut p.velocity_gradient,
            dd,
            by_matrix,
            strict,
        )?;
        restore_vec(
            c,
            "particles.half_size",
            &mut p.half_size,
            1,
            by_number,
            strict,
        )?;
        restore_vec(
            c,
            "particles.initial_position",
            &mut p.initial_position,
            D,
            by_vector,
            strict,
        )?;
        // Checkpoints from before loads existed have no such array: a scene without
        // loads needs none.
        let loaded = !p.external_force.is_empty();
        restore_vec(
            c,
            "particles.external_force",
            &mut p.external_force,
            D,
            by_vector,
            strict && loaded,
        )?;
        let ids = c.get("particles.id", n)?;
        let mut seen = vec![false; n];
        for (id, &value) in p.id.iter_mut().zip(ids) {
            let k = value as usize;
            if value < 0.0 || value.fract() != 0.0 || k >= n || seen[k] {
                return Err(CheckpointError::Invalid(
                    "the particle ids are not a permutation of the particles".into(),
                ));
            }
            seen[k] = true;
            *id = k as u32;
        }
        let fields = c.get("particles.contact_field", p.contact_field.len())?;
        for (f, &value) in p.contact_field.iter_mut().zip(fields) {
            *f = value as u8;
        }
        for (g, group) in p.groups.iter_mut().enumerate() {
            let len = group.range.len();
            for (j, values) in group.state.iter_mut().enumerate() {
                let name = format!("group.{g}.state.{j}");
                let components = values.len() / len.max(1);
                values.copy_from_slice(c.get(&name, len * components)?);
            }
        }
        let names: Vec<&'static str> = p.shared.names().to_vec();
        let mut carried = Vec::new();
        for name in names {
            if let Some(values) = p.shared.get_mut(name) {
                let key = format!("shared.{name}");
                if !strict && !c.arrays.contains_key(&key) {
                    continue;
                }
                let len = values.len();
                values.copy_from_slice(c.get(&key, len)?);
                carried.push(name);
            }
        }
        Ok(carried)
    }
}
