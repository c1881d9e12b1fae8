//! Capillary filling between plates with liquid particles (the work-in-progress scene
//! `docs/wip/capillary-filling-particles.json`): the volume correction keeps the liquid
//! that the meniscus pulls into the gap from thinning.

use crate::common;

use common::{example, load, run};

/// The fill's front at 0.5 s (the reference's: the particles' volume past the entrance
/// over the gap) and Washburn's, with `volume_correction` on or off.
fn front_at_half_a_second(volume_correction: bool) -> (f64, f64) {
    let overrides = [
        "solver.end_time=0.5".to_string(),
        "output.frames=5".to_string(),
        format!(
            "solver.mechanics={{\"incompressible\":{{\"volume_correction\":{volume_correction}}}}}"
        ),
    ];
    let scene = load(
        &example("../docs/wip/capillary-filling-particles.json"),
        &overrides,
    );
    let m = run(&scene);
    (
        m.measured_value.expect("front"),
        m.reference_value.expect("Washburn's front"),
    )
}

#[test]
fn the_volume_correction_keeps_a_capillary_fill_from_thinning() {
    // A 3 mm gap, 6 cells across, θ = 30°, σ = 0.07 N/m, μ = 0.3 Pa·s; Washburn's front
    // at 0.5 s is 10.05 mm. Measured (stop 82): with the correction 8.88 mm (−12%; at 1 s
    // 12.83 mm against 14.22, L2 error over the frames 0.119); without it 7.58 mm (−25%),
    // the liquid in the gap thinned by the meniscus's pull (README, "Capillary filling
    // with liquid particles"). Stop 81 read 10.31 mm with the correction and bounded it
    // within 8%: 85 of its particles had been drawn into the stick plates, where the
    // reference counted them as front (the correction filled every cell a stray particle
    // made liquid, the plates' too). Solid cells take no source since stop 82, and the
    // bound is now what separates the two: at least 0.85 of Washburn's with it, under
    // 0.8 without it (so the test fails if the setting stops acting).
    let (with, washburn) = front_at_half_a_second(true);
    assert!(
        (washburn - 10.05e-3).abs() < 1e-4,
        "Washburn's front {washburn}"
    );
    assert!(
        with > 0.85 * washburn && with < 1.05 * washburn,
        "front with the correction {with} against {washburn}"
    );
    let (without, _) = front_at_half_a_second(false);
    assert!(
        without < 0.8 * washburn,
        "front without the correction {without} against {washburn}"
    );
}
