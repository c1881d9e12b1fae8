//! The chart of `mpm rom study`, as the paper draws it: error against wall time per
//! simulated second (both logarithmic), one line per latent size with its sample counts
//! marked, the full-order run's time and real time (one second per simulated second) as
//! vertical lines; one panel for the position error and one for the displacement error.

use crate::rom::RomRow;
use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One of the study's error measures, read from a row.
type Measure = fn(&RomRow) -> Option<f64>;

fn err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> anyhow::Error {
    anyhow!("{e}")
}

/// A log-axis label with at most three significant digits (no exponent between 1e-3 and
/// 1e4), so neighbouring ticks do not run into each other.
fn short(v: f64) -> String {
    if (1e-3..1e4).contains(&v.abs()) {
        let text = format!("{v:.3}");
        let text = text.trim_end_matches('0').trim_end_matches('.');
        text.to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// Writes the study chart to `png`.
pub fn draw_study(png: &Path, title: &str, rows: &[RomRow], full_rate: f64) -> anyhow::Result<()> {
    crate::plot::register_font();
    let root = BitMapBackend::new(png, (1400, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(err)?;
    let panels = root.split_evenly((1, 2));
    let measures: [(&str, Measure); 2] = [
        ("relative L2 position error (the paper's)", |r| r.error),
        ("error relative to the displacement", |r| {
            r.error_to_displacement
        }),
    ];
    for (panel, (label, measure)) in panels.iter().zip(measures) {
        draw_panel(panel, rows, full_rate, label, measure)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    rows: &[RomRow],
    full_rate: f64,
    y_desc: &str,
    measure: Measure,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    let point = |r: &RomRow| {
        let (w, e) = (r.wall_per_simulated_second, measure(r)?);
        (w > 0.0 && w.is_finite() && e > 0.0).then_some((w, e, r.samples))
    };
    let points: Vec<(f64, f64, usize)> = rows.iter().filter_map(point).collect();
    // Real time (1 s per simulated second) and the full-order time are always in view.
    let (mut xmin, mut xmax) = (full_rate.min(1.0), full_rate.max(1.0));
    let (mut ymin, mut ymax) = (f64::MAX, f64::MIN);
    for (x, y, _) in &points {
        xmin = xmin.min(*x);
        xmax = xmax.max(*x);
        ymin = ymin.min(*y);
        ymax = ymax.max(*y);
    }
    if points.is_empty() {
        (ymin, ymax) = (1e-3, 1e-1);
    }
    let (y0, y1) = (ymin / 2.0, ymax * 2.0);
    let mut chart = ChartBuilder::on(area)
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((xmin / 2.0..xmax * 2.0).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("wall time per simulated second, s")
        .y_desc(y_desc)
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&|x| short(*x))
        .y_label_formatter(&|y| short(*y))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let mut latents: Vec<usize> = rows.iter().map(|r| r.latent).collect();
    latents.dedup();
    for (i, latent) in latents.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let mut pts: Vec<(f64, f64, usize)> = rows
            .iter()
            .filter(|r| r.latent == *latent)
            .filter_map(point)
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.0, p.1)),
                color.stroke_width(2),
            ))
            .map_err(err)?
            .label(format!("reduced, latent {latent}"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(
                pts.iter()
                    .map(|p| Circle::new((p.0, p.1), 4, color.filled())),
            )
            .map_err(err)?;
        chart
            .draw_series(pts.iter().map(|p| {
                Text::new(
                    format!("N={}", p.2),
                    (p.0, p.1),
                    ("sans-serif", 12).into_font(),
                )
            }))
            .map_err(err)?;
    }
    let vertical = |x: f64| vec![(x, y0), (x, y1)];
    chart
        .draw_series(LineSeries::new(vertical(full_rate), BLACK.stroke_width(2)))
        .map_err(err)?
        .label(format!("full order: {full_rate:.3} s per simulated second"))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    let blue = RGBColor(40, 90, 200);
    chart
        .draw_series(LineSeries::new(vertical(1.0), blue.stroke_width(2)))
        .map_err(err)?
        .label("real time: 1 s per simulated second")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue.stroke_width(2)));
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn log_labels_are_short() {
        assert_eq!(short(60.0), "60");
        assert_eq!(short(142.655), "142.655");
        assert_eq!(short(0.25), "0.25");
        assert_eq!(short(2e-5), "2e-5");
        assert_eq!(short(1e5), "1e5");
    }
}
