//! Labels: the length unit of the axes and numbers in at most four significant digits.

/// Length unit of the axes for a picture of `extent` metres: (name, metres to unit).
pub(crate) fn length_unit(extent: f64) -> (&'static str, f64) {
    if extent < 1e-4 {
        ("µm", 1e6)
    } else if extent < 0.1 {
        ("mm", 1e3)
    } else {
        ("m", 1.0)
    }
}

/// A number in at most four significant digits, without trailing zeros.
pub(crate) fn short(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        if s == "-0" { "0".into() } else { s }
    } else {
        let s = format!("{v:.3e}");
        let (mantissa, exponent) = s.split_once('e').expect("exponent form");
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        format!("{mantissa}e{exponent}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_and_numbers_read_well() {
        assert_eq!(length_unit(0.01), ("mm", 1e3));
        assert_eq!(length_unit(1.04e-3), ("mm", 1e3));
        assert_eq!(length_unit(5e-5), ("µm", 1e6));
        assert_eq!(length_unit(1.0), ("m", 1.0));
        assert_eq!(short(0.2), "0.2");
        assert_eq!(short(0.30000000000000004), "0.3");
        assert_eq!(short(2.0), "2");
        assert_eq!(short(399.99), "400");
        assert_eq!(short(300.0), "300");
        assert_eq!(short(-12.345), "-12.35");
        assert_eq!(short(1.5e-6), "1.5e-6");
        assert_eq!(short(2.0e9), "2e9");
        assert_eq!(short(0.0), "0");
        assert_eq!(short(f64::NAN), "n/a");
    }
}
