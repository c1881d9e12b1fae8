//! Drawing the picture: the particles as squares of their spacing coloured by value on equal
//! axes, the outlines of refined grid levels, the void markers, the title and the colour
//! bar, to a PNG file.

use super::colour::{NAN_GREY, colour_of, viridis};
use super::labels::{length_unit, short};
use super::levels::Segment;
use super::voids::Void;
use anyhow::anyhow;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// Everything [`draw`] needs.
pub(super) struct Picture<'a> {
    /// Particle positions, m.
    pub(super) points: &'a [(f64, f64)],
    /// The value of each particle.
    pub(super) values: &'a [f64],
    /// Range of the finite values.
    pub(super) range: (f64, f64),
    /// Particle spacing, m: the side of the drawn squares.
    pub(super) spacing: f64,
    /// Each particle's deformation in the picture's axes (row-major 2×2): the square is
    /// drawn as the parallelogram it maps to; `None`: upright squares.
    pub(super) shapes: Option<&'a [[f64; 4]]>,
    /// `[xmin, xmax, ymin, ymax]`, m.
    pub(super) bounds: [f64; 4],
    /// Title above the plot.
    pub(super) title: &'a str,
    /// Field label under the colour bar.
    pub(super) label: &'a str,
    /// Voids to mark.
    pub(super) voids: &'a [Void],
    /// The outline of each refined grid level, level 1 first, m.
    pub(super) levels: &'a [Vec<Segment>],
    /// Names of the axes drawn across and up.
    pub(super) axes: [&'a str; 2],
}

/// Long side of the plot area, px.
const LONG_SIDE: f64 = 1000.0;
const MARGIN: u32 = 20;
const TITLE_HEIGHT: u32 = 44;
const Y_LABEL_AREA: u32 = 80;
const X_LABEL_AREA: u32 = 56;
const RIGHT_PAD: u32 = 40;
const BAR_AREA: u32 = 70;
const BAR_WIDTH: u32 = 400;
const BAR_HEIGHT: u32 = 18;
const MIN_WIDTH: u32 = 720;
/// Outline colours of refined levels 1, 2, ...: white, orange, magenta, cyan.
const LEVEL_COLOURS: [RGBColor; 4] = [
    RGBColor(255, 255, 255),
    RGBColor(255, 150, 0),
    RGBColor(240, 0, 240),
    RGBColor(0, 220, 255),
];

fn err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> anyhow::Error {
    anyhow!("{e}")
}

/// Draws `p` to the PNG file `path`.
pub(super) fn draw(path: &Path, p: &Picture) -> anyhow::Result<()> {
    crate::plot::register_font();
    let [x0, x1, y0, y1] = p.bounds;
    let (w, h) = (x1 - x0, y1 - y0);
    let scale = LONG_SIDE / w.max(h);
    let plot_w = ((w * scale).round() as u32).max(1);
    let plot_h = ((h * scale).round() as u32).max(1);
    let chart_w = Y_LABEL_AREA + plot_w + RIGHT_PAD;
    let width = (chart_w + 2 * MARGIN).max(MIN_WIDTH);
    let height = MARGIN + TITLE_HEIGHT + plot_h + X_LABEL_AREA + BAR_AREA + MARGIN;
    let (ox, oy) = ((width - chart_w) / 2, MARGIN + TITLE_HEIGHT);

    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let centred = |size: u32, v: VPos| {
        TextStyle::from(("sans-serif", size).into_font()).pos(Pos::new(HPos::Center, v))
    };
    root.draw(&Text::new(
        p.title.to_string(),
        ((width / 2) as i32, (MARGIN + TITLE_HEIGHT / 2) as i32 - 4),
        centred(22, VPos::Center),
    ))
    .map_err(err)?;

    let (unit, factor) = length_unit(w.max(h));
    let area = root
        .clone()
        .shrink((ox, oy), (Y_LABEL_AREA + plot_w, plot_h + X_LABEL_AREA));
    let mut chart = ChartBuilder::on(&area)
        .margin(0)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x0 * factor..x1 * factor, y0 * factor..y1 * factor)
        .map_err(err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels((plot_w / 90).clamp(2, 12) as usize)
        .y_labels((plot_h / 60).clamp(2, 12) as usize)
        .x_desc(format!("{}, {unit}", p.axes[0]))
        .y_desc(format!("{}, {unit}", p.axes[1]))
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(err)?;

    // Pixels of the plot area, and the map from metres to them.
    let (xr, yr) = chart.plotting_area().get_pixel_range();
    let sx = (xr.end - xr.start) as f64 / w;
    let sy = (yr.end - yr.start) as f64 / h;
    let to_px = |x: f64, y: f64| {
        (
            xr.start as f64 + (x - x0) * sx,
            yr.start as f64 + (y1 - y) * sy,
        )
    };
    // Filled rectangles of the bitmap backend exclude their right and bottom edges: a
    // square covers the pixels [left, right) x [top, bottom), at least one.
    let half = (0.5 * p.spacing * sx).max(0.5);
    let clamp_x = |v: f64| (v as i32).clamp(xr.start, xr.end - 1);
    let clamp_y = |v: f64| (v as i32).clamp(yr.start, yr.end - 1);
    for (k, (&(x, y), &v)) in p.points.iter().zip(p.values).enumerate() {
        if let Some(f) = p.shapes.and_then(|s| s.get(k)) {
            // The square's corners mapped by F, in pixels (at least the one pixel an
            // upright square gets).
            let h = 0.5 * p.spacing;
            let corners: Vec<(i32, i32)> = [(-h, -h), (h, -h), (h, h), (-h, h)]
                .iter()
                .map(|&(u, w)| {
                    let (px, py) = to_px(x + f[0] * u + f[1] * w, y + f[2] * u + f[3] * w);
                    (px.round() as i32, py.round() as i32)
                })
                .collect();
            root.draw(&Polygon::new(corners, colour_of(v, p.range).filled()))
                .map_err(err)?;
            continue;
        }
        let (cx, cy) = to_px(x, y);
        let left = clamp_x((cx - half).floor());
        let right = ((cx + half).ceil() as i32).clamp(left + 1, xr.end);
        let top = clamp_y((cy - half).floor());
        let bottom = ((cy + half).ceil() as i32).clamp(top + 1, yr.end);
        root.draw(&Rectangle::new(
            [(left, top), (right, bottom)],
            colour_of(v, p.range).filled(),
        ))
        .map_err(err)?;
    }

    // Each level's outline: a black line under a coloured one, seen on any particle colour.
    for (k, segments) in p.levels.iter().enumerate() {
        let colour = LEVEL_COLOURS[k % LEVEL_COLOURS.len()];
        for (style, width) in [(BLACK, 4), (colour, 2)] {
            for s in segments {
                let ends: Vec<(i32, i32)> = s
                    .iter()
                    .map(|&(x, y)| {
                        let (px, py) = to_px(x, y);
                        (px.round() as i32, py.round() as i32)
                    })
                    .collect();
                root.draw(&PathElement::new(ends, style.stroke_width(width)))
                    .map_err(err)?;
            }
        }
    }

    let red = RGBColor(220, 20, 20);
    for void in p.voids {
        let (cx, cy) = to_px(void.x, void.y);
        let radius = (void.radius * sx).max(3.0);
        let centre = (cx.round() as i32, cy.round() as i32);
        root.draw(&Circle::new(
            centre,
            radius.round() as i32,
            red.stroke_width(2),
        ))
        .map_err(err)?;
        if let Some(id) = &void.id {
            let offset = (0.71 * radius).round() as i32 + 2;
            root.draw(&Text::new(
                id.clone(),
                (centre.0 + offset, centre.1 - offset),
                TextStyle::from(("sans-serif", 13).into_font())
                    .color(&red)
                    .pos(Pos::new(HPos::Left, VPos::Bottom)),
            ))
            .map_err(err)?;
        }
    }

    // Colour bar, under the x axis.
    let bar_left = (width - BAR_WIDTH) as i32 / 2;
    let bar_top = (oy + plot_h + X_LABEL_AREA + 10) as i32;
    let bar_bottom = bar_top + BAR_HEIGHT as i32 - 1;
    for i in 0..BAR_WIDTH as i32 {
        let t = i as f64 / (BAR_WIDTH - 1) as f64;
        root.draw(&Rectangle::new(
            [(bar_left + i, bar_top), (bar_left + i + 1, bar_bottom + 1)],
            viridis(t).filled(),
        ))
        .map_err(err)?;
    }
    let bar_right = bar_left + BAR_WIDTH as i32 - 1;
    root.draw(&Rectangle::new(
        [(bar_left, bar_top), (bar_right, bar_bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(err)?;
    let below = bar_bottom + 5;
    for (text, x) in [
        (short(p.range.0), bar_left),
        (short(p.range.1), bar_right),
        (p.label.to_string(), (bar_left + bar_right) / 2),
    ] {
        root.draw(&Text::new(text, (x, below), centred(15, VPos::Top)))
            .map_err(err)?;
    }
    if p.values.iter().any(|v| v.is_nan()) {
        let x = bar_right + 40;
        root.draw(&Rectangle::new(
            [(x, bar_top), (x + BAR_HEIGHT as i32, bar_bottom + 1)],
            NAN_GREY.filled(),
        ))
        .map_err(err)?;
        root.draw(&Text::new(
            "no value",
            (x + BAR_HEIGHT as i32 + 6, (bar_top + bar_bottom) / 2),
            TextStyle::from(("sans-serif", 15).into_font()).pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
