//! The explicit USL step of a scene with contact between bodies: P2G into every grid
//! velocity field, each field's own grid update (walls and obstacles act on every field),
//! the contact laws where fields meet (`contact`), then G2P from each particle's own field.
//! The work of friction (and stick) against the slip enters the energy ledger
//! (`EnergyLedger::friction`), and the run reports it (`contact.friction_work`, the
//! energy friction dissipated so far), the largest number of contact nodes and the times
//! contact starts and ends (table `contact`). The normal corrections of frictionless
//! contact are left out (see `ContactStats::work`): their loss shows as a fall of the
//! energy, which the growth check allows. Bonded interfaces (`cohesive`) are found at the
//! first step; the energy their laws dissipate enters the balance the same way
//! (`contact.cohesive_dissipation`) and the table `cohesive` follows the debonding.

use super::DimensionDispatch;
use super::contact::{FieldData, apply_contact};
use super::grid_update::{GridParams, damped_energy, update_grid};
use super::particle_to_grid::{ForceTerm, P2gParams};
use super::simulation::Simulation;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::scene::Transfer;

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// One explicit USL step with multi-field contact (bins already built this step).
    pub(super) fn contact_step(&mut self, dt: f64, physics: bool, force: ForceTerm) {
        let Some(fields) = self.contact.as_mut() else {
            return;
        };
        let params = P2gParams {
            dt,
            mass: true,
            force,
            force_apart: self.settings.transfer == Transfer::Flip,
            affine: self.settings.transfer == Transfer::Apic,
            inertia: K::APIC_INERTIA.unwrap_or(0.25),
            gravity: self.settings.gravity,
        };
        fields.scatter::<K>(&mut self.grid, &self.particles, &self.bins, params);
        for (volume, gradient) in fields.volume.iter_mut().zip(&mut fields.gradient) {
            self.boundaries.fold_symmetry_images(
                self.grid.nodes,
                self.grid.stride,
                volume,
                gradient,
            );
        }
        let time = self.relax_time.unwrap_or(self.time + dt);
        let grid_params = GridParams {
            dt,
            forces: true,
            flip: self.settings.transfer == Transfer::Flip,
            damping: self.settings.damping,
            time,
        };
        for grid in &mut fields.grids {
            // Damping is booked after the contact laws (below).
            let work = update_grid(grid, &self.boundaries, grid_params);
            self.ledger.boundaries += work.boundaries;
            self.ledger.friction += work.friction;
        }
        if let Some(cohesive) = fields.cohesive.as_mut() {
            let laws = &fields.laws;
            cohesive.bond(&fields.grids, &fields.gradient, &fields.volume, |a, b| {
                laws.cohesive(a, b).is_some()
            });
        }
        let stats = apply_contact(
            FieldData {
                grids: &mut fields.grids,
                gradient: &fields.gradient,
                volume: &fields.volume,
                laws: &fields.laws,
                cohesive: fields.cohesive.as_mut().map(|c| c.shared()),
                dt,
            },
            &self.boundaries,
            time,
        );
        if let Some(cohesive) = fields.cohesive.as_mut() {
            // The bonds dissipate energy: the balance subtracts it as work on the bodies.
            self.ledger.cohesive += stats.cohesive.dissipated;
            cohesive.record(
                stats.cohesive,
                self.time + dt,
                self.settings.end_time,
                &mut self.report,
            );
        }
        // Friction does work on the bodies: the energy balance subtracts it.
        self.ledger.friction -= stats.friction_work;
        fields.dissipated -= stats.friction_work;
        let touching = stats.nodes > 0;
        if touching != fields.touching {
            let row = vec![self.time + dt, stats.nodes as f64, 0.5 * stats.impulse / dt];
            self.report
                .table_mut("contact", &["time", "nodes", "force"])
                .rows
                .push(row);
            fields.touching = touching;
        }
        let damping = (-self.settings.damping * dt).exp();
        for grid in &mut fields.grids {
            // The laws changed velocities in front of stick and symmetry walls: the ghosts
            // behind them take the new mirror images (G2P reads them).
            self.boundaries.mirror_stick_walls(grid);
            self.ledger.damping += damped_energy(grid, damping);
        }
        self.report
            .record_max("contact.friction_work", fields.dissipated);
        self.report.record_max("contact.nodes", stats.nodes as f64);
        self.g2p(dt, true, true, true);
        self.average_volume(true, dt);
        if physics {
            self.advance_physics(dt, true);
        }
        self.update_stresses(dt);
    }
}
