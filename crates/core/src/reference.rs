//! Reference solutions a run measures its error against (closed forms and a shooting solve).

use crate::closed_forms::{
    capillary_fill_time, capillary_front, kamal_sourour_isothermal, neumann_lambda,
    poiseuille_startup_profile, semi_infinite_temperature, slab_temperature,
};
use crate::math::Vector;
use crate::output::Comparison;
use crate::particles::Particles;
use crate::scene::Reference;
use std::f64::consts::PI;

/// Accumulates the error of a run against a [`Reference`].
pub struct ReferenceTracker {
    reference: Reference,
    numerator: f64,
    denominator: f64,
    measured: Option<f64>,
    expected: Option<f64>,
    comparisons: Vec<Comparison>,
    /// Neumann's constant of a Stefan reference.
    lambda: f64,
    /// Time and measured front of every frame observed so far (capillary filling), until
    /// the front reached the end.
    fronts: Vec<(f64, f64)>,
}

impl ReferenceTracker {
    /// A tracker with nothing accumulated.
    pub fn new(reference: Reference) -> Self {
        let expected = match &reference {
            Reference::CantileverElastica {
                length,
                thickness,
                youngs_modulus,
                poisson_ratio,
                density,
                gravity,
                ..
            } => {
                let e_plane = youngs_modulus / (1.0 - poisson_ratio * poisson_ratio);
                let inertia = thickness.powi(3) / 12.0;
                let load = density * gravity * thickness;
                let alpha = load * length.powi(3) / (e_plane * inertia);
                Some(heavy_elastica_tip_deflection(alpha) * length)
            }
            Reference::TaylorBar { final_length, .. } => Some(*final_length),
            _ => None,
        };
        let lambda = match &reference {
            Reference::Stefan {
                melt_temperature,
                surface_temperature,
                initial_temperature,
                latent_heat,
                liquid,
                solid,
                ..
            } => {
                let diffusivity = |p: &crate::scene::PhaseProperties| {
                    p.conductivity / (p.density * p.specific_heat)
                };
                neumann_lambda(
                    liquid.specific_heat * (surface_temperature - melt_temperature) / latent_heat,
                    solid.specific_heat * (melt_temperature - initial_temperature) / latent_heat,
                    (diffusivity(liquid) / diffusivity(solid)).sqrt(),
                )
            }
            _ => 0.0,
        };
        Self {
            reference,
            numerator: 0.0,
            denominator: 0.0,
            measured: None,
            expected,
            comparisons: Vec::new(),
            lambda,
            fronts: Vec::new(),
        }
    }

    /// What the error measures, for the metrics.
    pub fn kind(&self) -> &'static str {
        match self.reference {
            Reference::VibratingBar { .. } => {
                "relative L2 error of particle displacement over all output frames (vibrating bar, first mode)"
            }
            Reference::CantileverElastica { .. } => {
                "relative error of the tip deflection at the end time against the heavy elastica"
            }
            Reference::TaylorBar { .. } => {
                "relative error of the final bar length against the published Taylor impact value"
            }
            Reference::SlabTemperature { .. } => {
                "RMS temperature error over particles and frames / temperature step (slab, Fourier series)"
            }
            Reference::SemiInfiniteTemperature { .. } => {
                "RMS temperature error over particles and frames / temperature step (semi-infinite body, erf solution)"
            }
            Reference::Stefan { .. } => {
                "relative L2 error of the melting front position over frames (Neumann solution)"
            }
            Reference::IsothermalCure { .. } => {
                "RMS error of the mean degree of cure over frames (Kamal-Sourour m = n = 1 closed form)"
            }
            Reference::AdiabaticCure { .. } => {
                "largest |T - T0 - (H/c) alpha| over particles and frames, divided by H/c"
            }
            Reference::CapillaryFilling { .. } => {
                "relative L2 error of the liquid front position over frames (capillary filling between plates, x² = hσcosθ t/(3μ))"
            }
            Reference::PoiseuilleStartup { .. } => {
                "RMS flow velocity error over particles and frames / steady centre-line velocity (plane Poiseuille start-up, series solution)"
            }
        }
    }

    /// Whether the tracker needs each particle's initial position.
    pub fn needs_initial_positions(&self) -> bool {
        matches!(
            self.reference,
            Reference::VibratingBar { .. } | Reference::CantileverElastica { .. }
        )
    }

    /// Takes one output frame into account.
    pub fn observe<const D: usize>(&mut self, particles: &Particles<D>, time: f64, last: bool) {
        match self.reference {
            Reference::VibratingBar {
                axis,
                fixed_end,
                length,
                amplitude,
                youngs_modulus,
                density,
            } => {
                // Displacement u = (A/ω) sin(π s / 2L) sin(ω t). Displacement rather than
                // velocity: the explicit update's velocity is second-order accurate only at
                // half steps, its positions at whole steps.
                let omega = PI * (youngs_modulus / density).sqrt() / (2.0 * length);
                let phase = (omega * time).sin() * amplitude / omega;
                for p in 0..particles.len() {
                    let x0 = particles.initial_position[p];
                    let s = x0[axis] - fixed_end;
                    let mut u_ref = Vector::<D>::zeros();
                    u_ref[axis] = (PI * s / (2.0 * length)).sin() * phase;
                    let u = particles.position[p] - x0;
                    let m = particles.mass[p];
                    self.numerator += m * (u - u_ref).norm_squared();
                    self.denominator += m * u_ref.norm_squared();
                }
            }
            Reference::CantileverElastica {
                axis, clamped_end, ..
            } => {
                if !last {
                    return;
                }
                // Mean deflection of the particles in the free end's last layer.
                let tip = (0..particles.len())
                    .map(|p| particles.initial_position[p][axis])
                    .fold(f64::NEG_INFINITY, f64::max);
                let across = if axis == 0 { 1 } else { 0 };
                let (mut sum, mut count) = (0.0, 0usize);
                for p in 0..particles.len() {
                    if tip - particles.initial_position[p][axis] < 1e-9 * (tip - clamped_end).abs()
                    {
                        sum +=
                            particles.initial_position[p][across] - particles.position[p][across];
                        count += 1;
                    }
                }
                self.measured = Some(sum / count.max(1) as f64);
            }
            Reference::TaylorBar {
                axis,
                wall,
                ref center,
                final_length,
                mushroom_diameter,
                peak_plastic_strain,
                ..
            } => {
                if !last {
                    return;
                }
                let shape = taylor_bar_shape(particles, axis, wall, center);
                self.measured = Some(shape.length);
                let mut compare = |quantity: &str, measured: f64, reference: f64| {
                    self.comparisons.push(Comparison {
                        quantity: quantity.into(),
                        measured,
                        reference,
                        relative_difference: (measured - reference) / reference,
                    })
                };
                compare("final_length", shape.length, final_length);
                compare(
                    "mushroom_diameter",
                    shape.impact_diameter,
                    mushroom_diameter,
                );
                if let Some(e) = peak_plastic_strain {
                    compare("peak_plastic_strain", shape.peak_plastic_strain, e);
                }
            }
            Reference::SlabTemperature {
                axis,
                min,
                max,
                initial_temperature,
                surface_temperature,
                diffusivity,
            } => self.observe_temperature(
                particles,
                time,
                initial_temperature - surface_temperature,
                |x| {
                    slab_temperature(
                        x[axis] - min,
                        time,
                        max - min,
                        diffusivity,
                        initial_temperature,
                        surface_temperature,
                    )
                },
            ),
            Reference::SemiInfiniteTemperature {
                axis,
                surface,
                initial_temperature,
                surface_temperature,
                diffusivity,
            } => self.observe_temperature(
                particles,
                time,
                initial_temperature - surface_temperature,
                |x| {
                    semi_infinite_temperature(
                        (x[axis] - surface).abs(),
                        time,
                        diffusivity,
                        initial_temperature,
                        surface_temperature,
                    )
                },
            ),
            Reference::Stefan {
                length, ref liquid, ..
            } => {
                let Some(solid_fraction) = particles.shared.get("solid_fraction") else {
                    return;
                };
                if time <= 0.0 {
                    return;
                }
                let (mut melted, mut total) = (0.0, 0.0);
                for (f, v) in solid_fraction.iter().zip(&particles.volume0) {
                    melted += (1.0 - f) * v;
                    total += v;
                }
                let front = length * melted / total.max(1e-300);
                let alpha_l = liquid.conductivity / (liquid.density * liquid.specific_heat);
                let exact = 2.0 * self.lambda * (alpha_l * time).sqrt();
                self.numerator += (front - exact).powi(2);
                self.denominator += exact * exact;
                self.measured = Some(front);
                self.expected = Some(exact);
            }
            Reference::IsothermalCure { k1, k2 } => {
                let Some(cure) = particles.shared.get("cure") else {
                    return;
                };
                if time <= 0.0 {
                    return;
                }
                let mean = cure.iter().sum::<f64>() / cure.len().max(1) as f64;
                let exact = kamal_sourour_isothermal(k1, k2, time);
                self.numerator += (mean - exact).powi(2);
                self.denominator += 1.0;
                self.measured = Some(mean);
                self.expected = Some(exact);
            }
            Reference::AdiabaticCure {
                initial_temperature,
                heat_of_reaction,
                specific_heat,
            } => {
                let (Some(cure), Some(temperature)) = (
                    particles.shared.get("cure"),
                    particles.shared.get("temperature"),
                ) else {
                    return;
                };
                let rise = heat_of_reaction / specific_heat;
                for (a, t) in cure.iter().zip(temperature) {
                    let e = (t - initial_temperature - rise * a).abs() / rise;
                    self.numerator = self.numerator.max(e);
                }
                self.denominator = 1.0;
            }
            Reference::CapillaryFilling {
                length,
                gap,
                surface_tension,
                contact_angle,
                viscosity,
                ..
            } => {
                let Some(fill) = particles.shared.get("fill") else {
                    return;
                };
                let (mut liquid, mut total) = (0.0, 0.0);
                for (f, v) in fill.iter().zip(&particles.volume0) {
                    liquid += f * v;
                    total += v;
                }
                let front = length * liquid / total.max(1e-300);
                let t_fill =
                    capillary_fill_time(length, gap, surface_tension, contact_angle, viscosity);
                self.observe_front(time, front, length, t_fill);
                if time <= 0.0 {
                    return;
                }
                let exact =
                    capillary_front(time, length, gap, surface_tension, contact_angle, viscosity);
                self.numerator += (front - exact).powi(2);
                self.denominator += exact * exact;
                self.measured = Some(front);
                self.expected = Some(exact);
            }
            Reference::PoiseuilleStartup {
                axis,
                cross_axis,
                wall,
                gap,
                pressure_gradient,
                viscosity,
                density,
            } => {
                let name = ["flow_velocity_x", "flow_velocity_y", "flow_velocity_z"];
                let Some(velocity) = name.get(axis).and_then(|n| particles.shared.get(n)) else {
                    return;
                };
                if time <= 0.0 || cross_axis >= D || velocity.is_empty() {
                    return;
                }
                let exact =
                    poiseuille_startup_profile(time, gap, pressure_gradient, viscosity, density);
                let centre = pressure_gradient * gap * gap / (8.0 * viscosity);
                let (mut sum, mut sum_exact) = (0.0, 0.0);
                for (x, u) in particles.position.iter().zip(velocity) {
                    let u_exact = exact(x[cross_axis] - wall);
                    self.numerator += ((u - u_exact) / centre).powi(2);
                    self.denominator += 1.0;
                    sum += u;
                    sum_exact += u_exact;
                }
                let n = velocity.len() as f64;
                self.measured = Some(sum / n);
                self.expected = Some(sum_exact / n);
            }
        }
    }

    /// Records one frame's capillary front and, the first time it reaches the end of the gap,
    /// the comparison `fill_time`.
    ///
    /// Under the law x² grows linearly in time, and the measured front stops at the end of
    /// the gap, so the frame that reached the end says only that the gap filled before it.
    /// The fill time is where the chord of x² through the last two frames before it reaches
    /// `length²` (kept between those frames), or with a single frame before it, where the
    /// chord from that frame to the full one does.
    fn observe_front(&mut self, time: f64, front: f64, length: f64, reference: f64) {
        let full = length * (1.0 - 1e-6);
        if self.fronts.last().is_some_and(|&(_, x)| x >= full) {
            return;
        }
        self.fronts.push((time, front));
        if front < full {
            return;
        }
        let k = self.fronts.len() - 1;
        if k == 0 {
            // Full at the first frame observed: when it filled is unknown.
            return;
        }
        let target = length * length;
        let (t_b, _) = self.fronts[k];
        let (t_a, x_a) = self.fronts[k - 1];
        let chord = |(t0, x0): (f64, f64), (t1, x1): (f64, f64)| {
            let slope = (x1 * x1 - x0 * x0) / (t1 - t0);
            (slope > 0.0 && slope.is_finite()).then(|| t1 + (target - x1 * x1) / slope)
        };
        let before = (k >= 2)
            .then(|| chord(self.fronts[k - 2], (t_a, x_a)))
            .flatten()
            .map(|t| t.max(t_a).min(t_b));
        let Some(measured) = before.or_else(|| chord((t_a, x_a), self.fronts[k])) else {
            return;
        };
        self.comparisons.push(Comparison {
            quantity: "fill_time".into(),
            measured,
            reference,
            relative_difference: (measured - reference) / reference,
        });
    }

    /// Adds one frame's squared temperature errors against `exact(position)`, each
    /// normalised by the temperature step (nothing at t = 0 or without temperatures).
    fn observe_temperature<const D: usize>(
        &mut self,
        particles: &Particles<D>,
        time: f64,
        step: f64,
        exact: impl Fn(&Vector<D>) -> f64,
    ) {
        let Some(temperature) = particles.shared.get("temperature") else {
            return;
        };
        if time <= 0.0 {
            return;
        }
        for (x, t) in particles.position.iter().zip(temperature) {
            self.numerator += (t - exact(x)).powi(2);
            self.denominator += step * step;
        }
    }

    /// Further quantities compared with the reference (empty for most references).
    pub fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }

    /// The error so far (`None` before anything was observed).
    pub fn error(&self) -> Option<f64> {
        match self.reference {
            Reference::VibratingBar { .. }
            | Reference::SlabTemperature { .. }
            | Reference::SemiInfiniteTemperature { .. }
            | Reference::Stefan { .. }
            | Reference::IsothermalCure { .. }
            | Reference::CapillaryFilling { .. }
            | Reference::PoiseuilleStartup { .. } => {
                (self.denominator > 0.0).then(|| (self.numerator / self.denominator).sqrt())
            }
            Reference::AdiabaticCure { .. } => (self.denominator > 0.0).then_some(self.numerator),
            Reference::CantileverElastica { .. } | Reference::TaylorBar { .. } => {
                let (m, e) = (self.measured?, self.expected?);
                Some((m - e).abs() / e.abs())
            }
        }
    }

    /// Reference value, where the error compares two numbers.
    pub fn expected(&self) -> Option<f64> {
        self.expected
    }

    /// Measured value, where the error compares two numbers.
    pub fn measured(&self) -> Option<f64> {
        self.measured
    }
}

/// Measured shape of an impacted bar.
struct BarShape {
    length: f64,
    impact_diameter: f64,
    peak_plastic_strain: f64,
}

/// Length, impact-face diameter and peak plastic strain of a bar standing on a wall.
///
/// Particle centres sit half a particle spacing inside the surface, so half the spacing
/// (from the particle's reference volume) is added at each measured surface. The impact
/// face is the particles within one spacing of the lowest one, and the length is measured
/// from there, so a bar that has rebounded off the wall measures true. The plastic strain is the state
/// field `plastic_strain` of whichever material has one (0 when none does).
fn taylor_bar_shape<const D: usize>(
    particles: &Particles<D>,
    axis: usize,
    wall: f64,
    center: &[f64],
) -> BarShape {
    let mut far = 0.0f64;
    let mut radius = 0.0f64;
    // The bar may have rebounded off the wall: the impact face is its lowest layer.
    let lowest = (0..particles.len())
        .map(|p| (particles.position[p][axis] - wall).abs())
        .fold(f64::INFINITY, f64::min);
    for p in 0..particles.len() {
        let x = particles.position[p];
        let half = 0.5 * particles.volume0[p].powf(1.0 / D as f64);
        let height = (x[axis] - wall).abs();
        far = far.max(height - lowest + 2.0 * half);
        if height - lowest < 2.0 * half {
            let mut r2 = 0.0;
            for (k, d) in (0..D).filter(|&d| d != axis).enumerate() {
                r2 += (x[d] - center.get(k).copied().unwrap_or(0.0)).powi(2);
            }
            radius = radius.max(r2.sqrt() + half);
        }
    }
    let mut peak = 0.0f64;
    for group in &particles.groups {
        let specs = group.material.state_fields();
        if let Some(f) = specs.iter().position(|s| s.name == "plastic_strain") {
            let c = specs[f].components;
            for value in group.state[f].iter().step_by(c) {
                peak = peak.max(*value);
            }
        }
    }
    BarShape {
        length: far,
        impact_diameter: 2.0 * radius,
        peak_plastic_strain: peak,
    }
}

/// Tip deflection over length of a clamped heavy elastica (inextensible beam under its own
/// uniform weight), with `alpha = w L³ / (E I)`.
///
/// Solves θ'' = −α (1 − s) cos θ on s ∈ [0, 1] with θ(0) = 0, θ'(1) = 0 by shooting on θ'(0)
/// (bisection; the end moment grows monotonically with it) and RK4, then integrates sin θ.
pub fn heavy_elastica_tip_deflection(alpha: f64) -> f64 {
    const STEPS: usize = 4000;
    let integrate = |k: f64| -> (f64, f64) {
        let h = 1.0 / STEPS as f64;
        let (mut th, mut om, mut defl) = (0.0f64, k, 0.0f64);
        let rhs = |s: f64, th: f64, om: f64| (om, -alpha * (1.0 - s) * th.cos(), th.sin());
        for i in 0..STEPS {
            let s = i as f64 * h;
            let k1 = rhs(s, th, om);
            let k2 = rhs(s + h / 2.0, th + h / 2.0 * k1.0, om + h / 2.0 * k1.1);
            let k3 = rhs(s + h / 2.0, th + h / 2.0 * k2.0, om + h / 2.0 * k2.1);
            let k4 = rhs(s + h, th + h * k3.0, om + h * k3.1);
            th += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            om += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            defl += h / 6.0 * (k1.2 + 2.0 * k2.2 + 2.0 * k3.2 + k4.2);
        }
        (om, defl)
    };
    let (mut lo, mut hi) = (0.0, alpha.max(1e-300));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if integrate(mid).0 < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    integrate(0.5 * (lo + hi)).1
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::physics::SharedFieldSpec;

    /// Particles at `positions` with volumes `volumes` and one shared field `name`.
    fn particles(positions: &[[f64; 2]], volumes: &[f64], name: &'static str) -> Particles<2> {
        let n = positions.len();
        let mut shared = crate::physics::ParticleFields::default();
        shared.add(SharedFieldSpec { name, initial: 0.0 }, n);
        Particles {
            position: positions
                .iter()
                .map(|p| Vector::<2>::new(p[0], p[1]))
                .collect(),
            velocity: vec![Vector::<2>::zeros(); n],
            mass: vec![1.0; n],
            volume0: volumes.to_vec(),
            deformation_gradient: Vec::new(),
            stress: Vec::new(),
            affine: Vec::new(),
            velocity_gradient: Vec::new(),
            half_size: Vec::new(),
            initial_position: Vec::new(),
            id: (0..n as u32).collect(),
            groups: Vec::new(),
            shared,
        }
    }

    fn capillary() -> Reference {
        Reference::CapillaryFilling {
            axis: 0,
            entrance: 0.0,
            length: 4e-3,
            gap: 5e-5,
            surface_tension: 0.03,
            contact_angle: 0.0,
            viscosity: 2.0,
        }
    }

    /// Sets the fill of four equal-volume particles so the measured front is `front` of
    /// `length` (the first particles full, the next one partly).
    fn set_front(p: &mut Particles<2>, front: f64, length: f64) {
        let fill = p.shared.get_mut("fill").unwrap();
        let filled = 4.0 * front / length;
        for (i, f) in fill.iter_mut().enumerate() {
            *f = (filled - i as f64).clamp(0.0, 1.0);
        }
    }

    #[test]
    fn capillary_filling_tracks_the_front_and_the_fill_time() {
        let (length, t_fill) = (4e-3, capillary_fill_time(4e-3, 5e-5, 0.03, 0.0, 2.0));
        let mut p = particles(&[[0.0; 2]; 4], &[1.0, 1.0, 1.0, 1.0], "fill");
        let mut r = ReferenceTracker::new(capillary());
        // Frames every t_fill/8, the front following the law exactly (held at the end).
        for k in 0..=12 {
            let t = k as f64 * t_fill / 8.0;
            set_front(&mut p, length * (t / t_fill).sqrt().min(1.0), length);
            r.observe(&p, t, k == 12);
            if k < 8 {
                assert!(r.comparisons().is_empty(), "{k}");
            }
        }
        assert!(r.error().unwrap() < 1e-12, "{:?}", r.error());
        assert_eq!(r.measured(), Some(length));
        assert!((r.expected().unwrap() - length).abs() < 1e-12 * length);
        let c = r.comparisons();
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].quantity, "fill_time");
        assert!((c[0].reference - t_fill).abs() < 1e-12 * t_fill);
        assert!(c[0].relative_difference.abs() < 1e-9, "{:?}", c[0]);

        // Filling between frames (at 7.5 of 8 frame intervals): the frame after says only
        // "full"; the chord of the frames before still finds the fill time.
        let mut r = ReferenceTracker::new(capillary());
        let slow = t_fill * 8.0 / 7.5;
        for k in 0..=10 {
            let t = k as f64 * t_fill / 8.0;
            set_front(&mut p, length * (t / slow).sqrt().min(1.0), length);
            r.observe(&p, t, k == 10);
        }
        let c = r.comparisons();
        assert_eq!(c.len(), 1);
        assert!((c[0].measured - slow).abs() < 1e-9 * slow, "{:?}", c[0]);
        // The front lags the law, and the error says by how much.
        assert!(r.error().unwrap() > 0.01);
    }

    #[test]
    fn capillary_filling_without_reaching_the_end_has_no_fill_time() {
        let t_fill = capillary_fill_time(4e-3, 5e-5, 0.03, 0.0, 2.0);
        let mut p = particles(&[[0.0; 2]; 4], &[1.0, 1.0, 1.0, 1.0], "fill");
        let mut r = ReferenceTracker::new(capillary());
        r.observe(&p, 0.0, false);
        assert!(r.error().is_none());
        // A front at half the exact one: relative L2 error 0.5.
        set_front(&mut p, 0.5 * 4e-3 * 0.5f64.sqrt(), 4e-3);
        r.observe(&p, 0.5 * t_fill, true);
        assert!((r.error().unwrap() - 0.5).abs() < 1e-12);
        assert!(r.comparisons().is_empty());
    }

    #[test]
    fn poiseuille_startup_error_is_relative_to_the_centre_line_velocity() {
        let (h, g, mu, rho) = (1e-3, 1e4, 0.5, 1000.0);
        let reference = Reference::PoiseuilleStartup {
            axis: 0,
            cross_axis: 1,
            wall: 2e-3,
            gap: h,
            pressure_gradient: g,
            viscosity: mu,
            density: rho,
        };
        let ys = [0.125e-3, 0.375e-3, 0.625e-3, 0.875e-3];
        let positions: Vec<[f64; 2]> = ys.iter().map(|y| [0.0, 2e-3 + y]).collect();
        let mut p = particles(&positions, &[1.0; 4], "flow_velocity_x");
        let mut r = ReferenceTracker::new(reference);
        r.observe(&p, 0.0, false);
        assert!(r.error().is_none());
        let t = 0.1 * rho * h * h / mu;
        let exact = poiseuille_startup_profile(t, h, g, mu, rho);
        let centre = g * h * h / (8.0 * mu);
        let u: Vec<f64> = ys.iter().map(|&y| exact(y) + 0.01 * centre).collect();
        p.shared
            .get_mut("flow_velocity_x")
            .unwrap()
            .copy_from_slice(&u);
        r.observe(&p, t, true);
        assert!((r.error().unwrap() - 0.01).abs() < 1e-12, "{:?}", r.error());
        let mean_exact = ys.iter().map(|&y| exact(y)).sum::<f64>() / 4.0;
        assert!((r.expected().unwrap() - mean_exact).abs() < 1e-12 * centre);
        assert!((r.measured().unwrap() - mean_exact - 0.01 * centre).abs() < 1e-12 * centre);
    }

    #[test]
    fn elastica_matches_linear_beam_theory_for_small_loads() {
        // Small deflection: δ/L = α/8.
        let alpha = 1e-3;
        let d = heavy_elastica_tip_deflection(alpha);
        assert!((d - alpha / 8.0).abs() / (alpha / 8.0) < 1e-4, "{d}");
    }

    #[test]
    fn elastica_is_below_linear_theory_for_large_loads() {
        // Large loads: the beam hangs, δ/L < 1 and below α/8.
        let d = heavy_elastica_tip_deflection(10.0);
        assert!(d < 10.0 / 8.0 && d > 0.5 && d < 1.0, "{d}");
    }
}
