//! The error-against-run-time plot of a study (PNG and SVG), drawn with plotters and a
//! bundled font (DejaVu Sans; its licence is in crates/cli/assets).

use crate::study::{StudyRow, observed_order, pareto_front, series};
use anyhow::{Context, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Registers the bundled font as "sans-serif" for plotters (once per process).
pub(crate) fn register_font() {
    REGISTER.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// A chart with logarithmic axes on both sides.
pub(crate) type LogLogChart<'a, DB> =
    ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// The log-log chart of error against time that both study plots draw on: axes spanning
/// `x` and `y` with some room, labelled `x_desc` and `y_desc`, the mesh drawn.
pub(crate) fn log_log_chart<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    title: &str,
    x: (f64, f64),
    y: (f64, f64),
    x_desc: &str,
    y_desc: &str,
) -> anyhow::Result<LogLogChart<'a, DB>>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 24))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(
            (x.0 / 1.5..x.1 * 1.5).log_scale(),
            (y.0 / 2.0..y.1 * 2.0).log_scale(),
        )
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|x| format!("{x:.2e}"))
        .y_label_formatter(&|y| format!("{y:.1e}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    Ok(chart)
}

/// Writes `study.png` and `study.svg` into `dir`.
pub fn draw(dir: &Path, title: &str, rows: &[StudyRow]) -> anyhow::Result<()> {
    register_font();
    let png = dir.join("study.png");
    let svg = dir.join("study.svg");
    draw_on(
        BitMapBackend::new(&png, (1000, 650)).into_drawing_area(),
        title,
        rows,
    )
    .with_context(|| format!("drawing {}", png.display()))?;
    draw_on(
        SVGBackend::new(&svg, (1000, 650)).into_drawing_area(),
        title,
        rows,
    )
    .with_context(|| format!("drawing {}", svg.display()))?;
    Ok(())
}

fn draw_on<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    rows: &[StudyRow],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    root.fill(&WHITE).map_err(err)?;
    let points: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| Some((r.wall_seconds?, r.error?)))
        .filter(|(w, e)| *w > 0.0 && *e > 0.0)
        .collect();
    if points.is_empty() {
        root.draw(&Text::new(
            "no run with an error and a wall time to plot",
            (40, 40),
            ("sans-serif", 20).into_font(),
        ))
        .map_err(err)?;
        root.present().map_err(err)?;
        return Ok(());
    }
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in &points {
        xmin = xmin.min(*x);
        xmax = xmax.max(*x);
        ymin = ymin.min(*y);
        ymax = ymax.max(*y);
    }
    let mut chart = log_log_chart(
        &root,
        title,
        (xmin, xmax),
        (ymin, ymax),
        "wall time, s",
        "error against the reference",
    )?;
    for (i, (name, group)) in series(rows).iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let mut pts: Vec<(f64, f64)> = group
            .iter()
            .filter_map(|r| Some((r.wall_seconds?, r.error?)))
            .collect();
        pts.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal));
        let label = match observed_order(group) {
            Some(order) => format!("{name} (order {order:.2})"),
            None => name.clone(),
        };
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, 4, color.filled())))
            .map_err(err)?;
    }
    let front: Vec<(f64, f64)> = pareto_front(rows)
        .iter()
        .filter_map(|r| Some((r.wall_seconds?, r.error?)))
        .collect();
    chart
        .draw_series(LineSeries::new(front.clone(), BLACK.stroke_width(1)))
        .map_err(err)?
        .label("Pareto front (no run is both faster and more accurate)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(1)));
    chart
        .draw_series(
            front
                .iter()
                .map(|p| Cross::new(*p, 7, BLACK.stroke_width(2))),
        )
        .map_err(err)?;
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}
