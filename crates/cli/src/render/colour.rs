//! The colour map: viridis, the grey of particles without a value, and the colour of a
//! value over the range of the finite values.

use plotters::prelude::RGBColor;

/// Smallest and largest finite value; NaN for both when there is none.
pub(super) fn finite_range(values: &[f64]) -> (f64, f64) {
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.iter().copied().filter(|v| v.is_finite()) {
        range = (range.0.min(v), range.1.max(v));
    }
    if range.0 > range.1 {
        (f64::NAN, f64::NAN)
    } else {
        range
    }
}

/// Viridis at 11 evenly spaced stops (matplotlib's), interpolated linearly.
const VIRIDIS: [(u8, u8, u8); 11] = [
    (68, 1, 84),
    (72, 36, 117),
    (65, 68, 135),
    (53, 95, 141),
    (42, 120, 142),
    (33, 145, 140),
    (34, 168, 132),
    (68, 191, 112),
    (122, 209, 81),
    (189, 223, 38),
    (253, 231, 37),
];

/// Colour of particles without a value (NaN).
pub(crate) const NAN_GREY: RGBColor = RGBColor(160, 160, 160);

/// The colour of `t` in [0, 1] (clamped) on a viridis-like map; NaN is grey.
pub(crate) fn viridis(t: f64) -> RGBColor {
    if t.is_nan() {
        return NAN_GREY;
    }
    let s = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The colour of `v` on the map over `range`; a range of one value is mid-map.
pub(super) fn colour_of(v: f64, range: (f64, f64)) -> RGBColor {
    if v.is_nan() {
        NAN_GREY
    } else if range.1 > range.0 {
        viridis((v - range.0) / (range.1 - range.0))
    } else {
        viridis(0.5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_map_runs_from_dark_purple_to_yellow_and_greys_nan() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(0.5), RGBColor(33, 145, 140));
        // Clamped outside [0, 1], infinities included.
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(f64::INFINITY), viridis(1.0));
        assert_eq!(viridis(f64::NAN), NAN_GREY);
        // Between two stops: halfway.
        assert_eq!(viridis(0.05), RGBColor(70, 19, 101));
        // Brightness rises along the map (a perceptually ordered map).
        let luma = |c: RGBColor| 0.299 * c.0 as f64 + 0.587 * c.1 as f64 + 0.114 * c.2 as f64;
        let mut last = -1.0;
        for i in 0..=100 {
            let l = luma(viridis(i as f64 / 100.0));
            assert!(l >= last, "luma falls at {i}%: {l} < {last}");
            last = l;
        }
        // Over a range; a range of one value is mid-map.
        assert_eq!(colour_of(400.0, (300.0, 400.0)), viridis(1.0));
        assert_eq!(colour_of(350.0, (350.0, 350.0)), viridis(0.5));
        assert_eq!(colour_of(f64::NAN, (0.0, 1.0)), NAN_GREY);
    }
}
