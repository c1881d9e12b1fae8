//! Unit tests across the plugin's parts: bump layout, lattice geometry, and a 1D
//! Hele-Shaw fill whose front follows the parallel-plate law.

use crate::front::{FRONT, FULL, FlowState};
use crate::hele_shaw::{HeleShawWork, solve_pressure};
use crate::lattice::{LatticeInput, build};
use crate::parameters::{BumpArray, BumpPattern, FlowMode, Reservoir};
use mpm_core::scene::Side;

fn bumps(pattern: BumpPattern) -> BumpArray {
    BumpArray {
        diameter: 1e-4,
        pitch: 2.5e-4,
        pattern,
        min: [0.0, 0.0],
        max: [1e-3, 1e-3],
        wetting: false,
    }
}

#[test]
fn bump_arrays_lay_out_square_and_staggered_rows() {
    assert_eq!(bumps(BumpPattern::Square).centres().len(), 16);
    let staggered = bumps(BumpPattern::Staggered).centres();
    // Shifted rows lose the bump that would stick out past the region.
    assert_eq!(staggered.len(), 4 + 3 + 4 + 3);
    assert!((staggered[4][0] - 2.5e-4).abs() < 1e-12);
}

fn strip(n: usize, dx: f64, bumps: Option<&BumpArray>) -> crate::lattice::Lattice {
    // One row of open cells between closed padding, reservoir on x-, vent on x+.
    let mut particles = Vec::new();
    for i in 0..n {
        for j in 0..n {
            particles.push(([(i as f64 + 0.5) * dx, (j as f64 + 0.5) * dx], dx * dx));
        }
    }
    let reservoirs = [Reservoir {
        sides: vec![Side::XMin],
        pressure: 0.0,
        span: None,
    }];
    build(&LatticeInput {
        n: [n, n],
        origin: [0.0, 0.0],
        dx,
        domain: ([0.0, 0.0], [n as f64 * dx, n as f64 * dx]),
        particles: &particles,
        mode: FlowMode::GapAveraged,
        wetting_tension: 0.03,
        gap: Some(5e-5),
        gap_axis: 1,
        bumps,
        reservoirs: &reservoirs,
        vents: &[Side::XMax],
        vent_regions: &[],
    })
}

#[test]
fn bumps_take_their_area_out_of_the_open_space() {
    let dx = 2.5e-5;
    let b = bumps(BumpPattern::Square);
    let lattice = strip(40, dx, Some(&b));
    let open: f64 = lattice.open.iter().sum::<f64>() * dx * dx;
    let expected = 1e-6 - 16.0 * std::f64::consts::PI * 0.25e-8;
    assert!(
        (open - expected).abs() < 0.01 * expected,
        "{open} {expected}"
    );
    assert_eq!(lattice.reservoirs.len(), 40);
    assert_eq!(lattice.vented.iter().filter(|&&v| v).count(), 40);
}

#[test]
fn a_filling_strip_conserves_volume_and_follows_the_square_root_law() {
    let dx = 1e-4;
    let n = 40;
    let lattice = strip(n, dx, None);
    let mut state = FlowState::new(&lattice, vec![0.0; lattice.len()]);
    state.viscosity.fill(0.1);
    let mut work = HeleShawWork::new(lattice.len());
    let (h, wetting, mu) = (5e-5, 0.03, 0.1);
    let mut time = 0.0;
    let mut injected = 0.0;
    while time < 2.0 {
        let solved = solve_pressure(&lattice, &mut state, &mut work, 1e-10, 10_000);
        assert!(solved.converged);
        let dt = (0.3 * state.fill_time_scale(&lattice)).min(2.0 - time);
        injected += dt * state.reservoir_flux.iter().sum::<f64>();
        state.advance(&lattice, dt);
        time += dt;
        assert!(state.state.iter().any(|&s| s == FRONT || s == FULL));
    }
    let (liquid, open) = state.volumes(&lattice);
    assert!(
        (liquid - injected).abs() < 1e-9 * open,
        "{liquid} {injected}"
    );
    let front = liquid / (open / (n as f64 * dx));
    let exact = (h * wetting * time / (3.0 * mu)).sqrt();
    assert!((front - exact).abs() < 0.02 * exact, "{front} {exact}");
}
