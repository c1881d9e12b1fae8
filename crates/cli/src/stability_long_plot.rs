//! The picture of a scene's long runs (PNG): the relative change of the total energy and,
//! where recorded, of the angular momentum against time, a line per transfer; drawn with
//! plotters and the bundled font. The vertical axis is linear (a symmetric-log axis turned
//! the bar's energy, which swings about its start within each period, into noise), from the
//! lowest change to the highest; the legend gives each line's final value.

use crate::plot::register_font;
use crate::stability_long::{LongCase, LongRun};
use anyhow::{Context, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Width and height of a picture, pixels.
pub const SIZE: (u32, u32) = (1000, 480);

/// The colour of each transfer's line.
fn colour(transfer: &str) -> RGBColor {
    match transfer {
        "pic" => RGBColor(215, 48, 39),
        "flip" => RGBColor(253, 141, 60),
        "apic" => RGBColor(26, 152, 80),
        "mls" => RGBColor(49, 130, 189),
        _ => RGBColor(0, 0, 0),
    }
}

/// Line width of each transfer: APIC wider, so that MLS (often on top of it) leaves it seen.
fn width(transfer: &str) -> u32 {
    if transfer == "apic" { 4 } else { 2 }
}

/// Writes the picture of `case`'s `runs` to `path` (PNG).
pub fn draw(path: &Path, case: &LongCase, runs: &[LongRun]) -> anyhow::Result<()> {
    register_font();
    draw_on(
        BitMapBackend::new(path, SIZE).into_drawing_area(),
        case,
        runs,
    )
    .with_context(|| format!("drawing {}", path.display()))
}

fn draw_on<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    case: &LongCase,
    runs: &[LongRun],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    root.fill(&WHITE).map_err(err)?;
    let steps = runs.iter().map(|r| r.steps).max().unwrap_or(0);
    let root = root
        .titled(
            &format!("Long runs: {}, {steps} steps", case.what),
            ("sans-serif", 16),
        )
        .map_err(err)?;
    type Series<'a> = (&'a str, Box<dyn Fn(&LongRun) -> Option<&[f64]>>);
    let mut panels: Vec<Series> = vec![(
        "energy (E − E₀) / E₀",
        Box::new(|r: &LongRun| Some(r.energy_change.as_slice())),
    )];
    if case.free {
        panels.push((
            "angular momentum (L − L₀) / L₀",
            Box::new(|r: &LongRun| r.angular_momentum_change.as_deref()),
        ));
    }
    let areas = root.split_evenly((1, panels.len()));
    let t_end = runs
        .iter()
        .filter_map(|r| r.time.last())
        .fold(0.0f64, |a, &b| a.max(b))
        .max(1e-12);
    for (area, (label, series)) in areas.iter().zip(&panels) {
        let values = runs
            .iter()
            .filter_map(series)
            .flatten()
            .filter(|v| v.is_finite());
        let (lo, hi) = values.fold((0.0f64, 0.0f64), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let pad = 0.05 * (hi - lo).max(1e-3);
        let (lo, hi) = (lo - pad, hi + pad);
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_end, lo..hi)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time, s")
            .y_desc(*label)
            .y_label_formatter(&|y| format!("{:.2}", y + 0.0))
            .light_line_style(WHITE)
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        for run in runs {
            let Some(values) = series(run) else {
                continue;
            };
            let (c, w) = (colour(&run.transfer), width(&run.transfer));
            let points: Vec<(f64, f64)> = run
                .time
                .iter()
                .zip(values)
                .filter(|(_, v)| v.is_finite())
                .map(|(t, v)| (*t, *v))
                .collect();
            chart
                .draw_series(LineSeries::new(points, c.stroke_width(w)))
                .map_err(err)?
                .label(format!(
                    "{} ({:+.2e})",
                    run.transfer,
                    values.last().copied().unwrap_or(f64::NAN)
                ))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], c.stroke_width(w)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::MiddleRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
