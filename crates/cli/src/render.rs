//! `mpm render`: one frame of a 2D result store as a PNG picture of the particles coloured
//! by a field (equal axes, a viridis colour bar), for documentation pictures; optionally
//! with the voids of a table in the store's metrics marked as red circles.

use crate::exit_status::input_error;
use anyhow::{Context, anyhow, bail};
use mpm_io::ResultStore;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use serde_json::Value;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// What to draw, as given on the command line.
#[derive(Debug)]
pub(crate) struct RenderArgs {
    /// Result store.
    pub store: PathBuf,
    /// Particle field to colour by.
    pub field: String,
    /// Frame; negative counts from the end; `None` is the last.
    pub frame: Option<i64>,
    /// Flat component index of a vector or tensor field.
    pub component: usize,
    /// PNG file to write.
    pub out: PathBuf,
    /// Title instead of the default one.
    pub title: Option<String>,
    /// Name of a metrics table of voids to mark.
    pub voids: Option<String>,
}

/// What was drawn.
#[derive(Debug)]
pub(crate) struct Rendered {
    /// Frame index.
    pub frame: u64,
    /// Time of the frame, s.
    pub time: f64,
    /// Particles drawn.
    pub particles: usize,
    /// Field label (with the component of a vector or tensor field).
    pub label: String,
    /// Range of the finite values (NaN when there are none).
    pub range: (f64, f64),
    /// Voids marked, when a table was drawn.
    pub voids: Option<usize>,
}

/// Reads one frame of `args.store` and writes the picture to `args.out`.
pub(crate) fn render(args: &RenderArgs) -> anyhow::Result<Rendered> {
    let is_png = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        return Err(input_error!(
            "--out `{}`: the picture is written as PNG; give a file name ending in .png",
            args.out.display()
        ));
    }
    let store = ResultStore::open(&args.store)
        .with_context(|| format!("cannot open result store `{}`", args.store.display()))?;
    let dim = store.dimension();
    if dim != 2 {
        return Err(input_error!(
            "render draws 2D stores only; `{}` holds a {dim}D run",
            args.store.display()
        ));
    }
    let fields = store.fields()?;
    if !fields.contains(&args.field) {
        return Err(input_error!(
            "field `{}` is not in `{}`; available fields: {}",
            args.field,
            args.store.display(),
            fields.join(", ")
        ));
    }
    if !fields.iter().any(|f| f == "x") {
        return Err(input_error!(
            "`{}` stores no particle positions (field `x`); available fields: {}",
            args.store.display(),
            fields.join(", ")
        ));
    }
    let times = store.times()?;
    let k = resolve_frame(args.frame, times.len() as u64)?;
    let time = times[k as usize];

    let (_, positions) = store.frame("x", k)?;
    let n = positions.len() / 2;
    let (shape, values) = store.frame(&args.field, k)?;
    let components: usize = shape.iter().skip(1).product::<u64>() as usize;
    if shape.first().copied() != Some(n as u64) || values.len() != n * components {
        bail!(
            "field `{}` has shape {shape:?} per frame, which does not match the {n} particles of `x`",
            args.field
        );
    }
    if args.component >= components {
        return Err(input_error!(
            "field `{}` has {components} component(s) per particle (shape {:?}); --component must be below {components}",
            args.field,
            &shape[1..]
        ));
    }
    let label = if components > 1 {
        format!("{}[{}]", args.field, args.component)
    } else {
        args.field.clone()
    };

    let mut points = Vec::with_capacity(n);
    let mut scalar = Vec::with_capacity(n);
    for p in 0..n {
        let (x, y) = (positions[2 * p], positions[2 * p + 1]);
        if x.is_finite() && y.is_finite() {
            points.push((x, y));
            scalar.push(values[p * components + args.component]);
        }
    }

    let voids = match &args.voids {
        None => None,
        Some(table) => match parse_voids(store.attributes().get("metrics"), table) {
            Ok(t) => {
                if t.skipped > 0 {
                    eprintln!(
                        "warning: {} row(s) of table `{table}` lack a finite x, y or area; not drawn",
                        t.skipped
                    );
                }
                Some(t.voids)
            }
            Err(message) => {
                eprintln!("warning: {message}; drawing without voids");
                None
            }
        },
    };

    let attributes = store.attributes();
    let scene = attributes
        .get("scene")
        .and_then(|s| s.get("name"))
        .and_then(Value::as_str)
        .map(str::to_string)
        .unwrap_or_else(|| {
            args.store
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "result".into())
        });
    let mut title = args
        .title
        .clone()
        .unwrap_or_else(|| format!("{scene} — {label} at t = {} s", short(time)));
    if let Some(v) = &voids {
        let noun = if v.len() == 1 { "void" } else { "voids" };
        title = format!("{title}, {} {noun}", v.len());
    }

    let spacing = particle_spacing(&points);
    let bounds = picture_bounds(&points, domain(attributes), spacing.unwrap_or(0.0))
        .context("nothing to draw: no particle positions and no domain in the store")?;
    let spacing = spacing.unwrap_or_else(|| {
        let (w, h) = (bounds[1] - bounds[0], bounds[3] - bounds[2]);
        (w * h / points.len().max(1) as f64).sqrt()
    });
    let range = finite_range(&scalar);

    std::fs::File::create(&args.out)
        .with_context(|| format!("cannot write `{}`", args.out.display()))?;
    let picture = Picture {
        points: &points,
        values: &scalar,
        range,
        spacing,
        bounds,
        title: &title,
        label: &label,
        voids: voids.as_deref().unwrap_or(&[]),
    };
    if let Err(e) = draw(&args.out, &picture) {
        let _ = std::fs::remove_file(&args.out);
        return Err(e.context(format!("drawing `{}`", args.out.display())));
    }
    Ok(Rendered {
        frame: k,
        time,
        particles: points.len(),
        label,
        range,
        voids: voids.map(|v| v.len()),
    })
}

/// The frame index of `frame` (negative counts from the end; `None` is the last) in a store
/// of `count` frames.
fn resolve_frame(frame: Option<i64>, count: u64) -> anyhow::Result<u64> {
    if count == 0 {
        return Err(input_error!("the store has no frames"));
    }
    let k = frame.unwrap_or(-1);
    let index = if k < 0 { count as i64 + k } else { k };
    if index < 0 || index >= count as i64 {
        return Err(input_error!(
            "frame {k} is out of range: the store has {count} frame(s), 0 to {} (or -{count} to -1 from the end)",
            count - 1
        ));
    }
    Ok(index as u64)
}

/// The scene's domain box `[xmin, xmax, ymin, ymax]`, when the store records it.
fn domain(attributes: &serde_json::Map<String, Value>) -> Option<[f64; 4]> {
    let d = attributes.get("scene")?.get("domain")?;
    let corner = |key: &str| -> Option<(f64, f64)> {
        let c = d.get(key)?.as_array()?;
        Some((c.first()?.as_f64()?, c.get(1)?.as_f64()?))
    };
    let (min, max) = (corner("min")?, corner("max")?);
    let b = [min.0, max.0, min.1, max.1];
    (b.iter().all(|v| v.is_finite()) && b[1] > b[0] && b[3] > b[2]).then_some(b)
}

/// The drawn box: the domain (so that frames of a run share their framing) and every
/// particle's square, `[xmin, xmax, ymin, ymax]`, never of zero extent.
fn picture_bounds(
    points: &[(f64, f64)],
    domain: Option<[f64; 4]>,
    spacing: f64,
) -> Option<[f64; 4]> {
    let half = 0.5 * spacing;
    let mut b = domain.unwrap_or([f64::MAX, f64::MIN, f64::MAX, f64::MIN]);
    for &(x, y) in points {
        b[0] = b[0].min(x - half);
        b[1] = b[1].max(x + half);
        b[2] = b[2].min(y - half);
        b[3] = b[3].max(y + half);
    }
    if b[0] > b[1] || b[2] > b[3] {
        return None;
    }
    // A single particle, or a line of them: give the flat direction some extent.
    let size = (b[1] - b[0]).max(b[3] - b[2]);
    let size = if size > 0.0 { size } else { 1e-3 };
    for axis in [0, 2] {
        if b[axis + 1] - b[axis] < 1e-3 * size {
            let mid = 0.5 * (b[axis] + b[axis + 1]);
            b[axis] = mid - 0.05 * size;
            b[axis + 1] = mid + 0.05 * size;
        }
    }
    Some(b)
}

/// Smallest and largest finite value; NaN for both when there is none.
fn finite_range(values: &[f64]) -> (f64, f64) {
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

/// Estimated particle spacing: the median distance to the nearest other particle, over up
/// to 2000 particles, found with a bucket grid. `None` for fewer than two distinct points.
pub(crate) fn particle_spacing(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let (w, h) = (x1 - x0, y1 - y0);
    let cell = if w * h > 0.0 {
        (w * h / n as f64).sqrt()
    } else {
        w.max(h) / (n - 1) as f64
    };
    if cell.is_nan() || cell <= 0.0 {
        return None;
    }
    let key = |(x, y): (f64, f64)| {
        (
            ((x - x0) / cell).floor() as i64,
            ((y - y0) / cell).floor() as i64,
        )
    };
    let mut buckets: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        buckets.entry(key(p)).or_default().push(i);
    }
    // Rings of buckets around a particle, nearest first; a point in ring r + 1 is at least
    // r cells away, so the search stops once the nearest found is closer than that.
    const MAX_RING: i64 = 64;
    let mut nearest = Vec::new();
    for i in (0..n).step_by((n / 2000).max(1)) {
        let p = points[i];
        let (cx, cy) = key(p);
        let mut best = f64::INFINITY;
        for r in 0..=MAX_RING {
            for dx in -r..=r {
                let edge = dx.abs() == r;
                let dys: Vec<i64> = if edge {
                    (-r..=r).collect()
                } else {
                    vec![-r, r]
                };
                for dy in dys {
                    for &j in buckets.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                        let d = (points[j].0 - p.0).hypot(points[j].1 - p.1);
                        if j != i && d > 0.0 && d < best {
                            best = d;
                        }
                    }
                }
            }
            if best <= r as f64 * cell {
                break;
            }
        }
        if best.is_finite() {
            nearest.push(best);
        }
    }
    if nearest.is_empty() {
        return None;
    }
    nearest.sort_by(f64::total_cmp);
    Some(nearest[nearest.len() / 2])
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
fn colour_of(v: f64, range: (f64, f64)) -> RGBColor {
    if v.is_nan() {
        NAN_GREY
    } else if range.1 > range.0 {
        viridis((v - range.0) / (range.1 - range.0))
    } else {
        viridis(0.5)
    }
}

/// One void of a metrics table.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Void {
    /// Centre, m.
    pub x: f64,
    /// Centre, m.
    pub y: f64,
    /// Area, m².
    pub area: f64,
    /// The row's `id`, if the table has that column.
    pub id: Option<String>,
}

/// The voids of a table, and how many rows were left out.
#[derive(Debug)]
pub(crate) struct VoidTable {
    /// Rows with a finite x, y and a non-negative area.
    pub voids: Vec<Void>,
    /// Rows without.
    pub skipped: usize,
}

/// Reads table `table` of the store's `metrics` attribute:
/// `tables: { TABLE: { columns: [...], rows: [[...], ...] } }` with columns `x`, `y`, `area`
/// (and optionally `id`). Rows may also be objects keyed by column. The error is a message
/// for a warning.
pub(crate) fn parse_voids(metrics: Option<&Value>, table: &str) -> Result<VoidTable, String> {
    let tables = metrics
        .and_then(|m| m.get("tables"))
        .and_then(Value::as_object)
        .ok_or_else(|| format!("no table `{table}`: the store's metrics carry no tables"))?;
    let t = tables.get(table).ok_or_else(|| {
        let names: Vec<&str> = tables.keys().map(String::as_str).collect();
        format!(
            "no table `{table}` in the store's metrics (tables: {})",
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        )
    })?;
    let columns: Vec<&str> = t
        .get("columns")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("table `{table}` has no `columns` list"))?
        .iter()
        .map(|c| c.as_str().unwrap_or(""))
        .collect();
    let column = |name: &str| columns.iter().position(|c| *c == name);
    let (Some(ix), Some(iy), Some(ia)) = (column("x"), column("y"), column("area")) else {
        return Err(format!(
            "table `{table}` needs columns x, y and area; it has {}",
            columns.join(", ")
        ));
    };
    let iid = column("id");
    let rows = t
        .get("rows")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("table `{table}` has no `rows` list"))?;
    let mut out = VoidTable {
        voids: Vec::new(),
        skipped: 0,
    };
    for row in rows {
        let cell = |i: usize| -> Option<&Value> {
            match row {
                Value::Array(cells) => cells.get(i),
                Value::Object(map) => map.get(columns[i]),
                _ => None,
            }
        };
        let number = |i: usize| cell(i).and_then(Value::as_f64).filter(|v| v.is_finite());
        match (number(ix), number(iy), number(ia)) {
            (Some(x), Some(y), Some(area)) if area >= 0.0 => {
                let id = iid.and_then(cell).and_then(|v| match v {
                    Value::Null => None,
                    Value::String(s) => Some(s.clone()),
                    // Tables of numbers carry ids as floats: 3.0 is "3".
                    Value::Number(n) => Some(match n.as_f64() {
                        Some(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!("{}", f as i64),
                        _ => n.to_string(),
                    }),
                    other => Some(other.to_string()),
                });
                out.voids.push(Void { x, y, area, id });
            }
            _ => out.skipped += 1,
        }
    }
    Ok(out)
}

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

/// Everything [`draw`] needs.
struct Picture<'a> {
    points: &'a [(f64, f64)],
    values: &'a [f64],
    range: (f64, f64),
    spacing: f64,
    /// `[xmin, xmax, ymin, ymax]`, m.
    bounds: [f64; 4],
    title: &'a str,
    label: &'a str,
    voids: &'a [Void],
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

fn err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> anyhow::Error {
    anyhow!("{e}")
}

fn draw(path: &Path, p: &Picture) -> anyhow::Result<()> {
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
        .x_desc(format!("x, {unit}"))
        .y_desc(format!("y, {unit}"))
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
    for (&(x, y), &v) in p.points.iter().zip(p.values) {
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

    let red = RGBColor(220, 20, 20);
    for void in p.voids {
        let (cx, cy) = to_px(void.x, void.y);
        let radius = ((void.area / std::f64::consts::PI).sqrt() * sx).max(3.0);
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

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

    #[test]
    fn void_tables_are_read_from_the_metrics() {
        let metrics = json!({
            "outcome": "finished",
            "tables": {
                "voids": {
                    "columns": ["id", "x", "y", "area", "frame"],
                    "rows": [
                        [1, 3e-4, 5e-5, 7.0e-10, 4],
                        ["B", 5.5e-4, 6e-5, 2.5e-10, 4],
                        [7.0, 2e-4, 2e-5, 1e-10, 4],
                        [null, 7.5e-4, 4.5e-5, 0.0, 4],
                        [4, "far", 4.5e-5, 1e-10, 4],
                        [5, 1e-4, 1e-5, -1.0, 4],
                        [6, 1e-4]
                    ]
                },
                "fronts": { "columns": ["t", "x"], "rows": [[0.0, 0.0]] }
            }
        });
        let t = parse_voids(Some(&metrics), "voids").unwrap();
        assert_eq!(t.skipped, 3);
        assert_eq!(
            t.voids,
            vec![
                Void {
                    x: 3e-4,
                    y: 5e-5,
                    area: 7.0e-10,
                    id: Some("1".into())
                },
                Void {
                    x: 5.5e-4,
                    y: 6e-5,
                    area: 2.5e-10,
                    id: Some("B".into())
                },
                Void {
                    x: 2e-4,
                    y: 2e-5,
                    area: 1e-10,
                    id: Some("7".into())
                },
                Void {
                    x: 7.5e-4,
                    y: 4.5e-5,
                    area: 0.0,
                    id: None
                },
            ]
        );

        // Rows as objects; no id column.
        let metrics = json!({ "tables": { "v": {
            "columns": ["x", "y", "area"],
            "rows": [{ "x": 1.0, "y": 2.0, "area": 3.0 }]
        } } });
        let t = parse_voids(Some(&metrics), "v").unwrap();
        assert_eq!(
            t.voids,
            vec![Void {
                x: 1.0,
                y: 2.0,
                area: 3.0,
                id: None
            }]
        );

        // Missing tables and columns are messages naming what there is.
        let e = parse_voids(Some(&metrics), "voids").unwrap_err();
        assert!(
            e.contains("no table `voids`") && e.contains("tables: v"),
            "{e}"
        );
        let e = parse_voids(Some(&json!({"tables": {}})), "voids").unwrap_err();
        assert!(e.contains("tables: none"), "{e}");
        let e = parse_voids(Some(&json!({"outcome": "finished"})), "voids").unwrap_err();
        assert!(e.contains("no tables"), "{e}");
        assert!(parse_voids(Some(&Value::Null), "voids").is_err());
        assert!(parse_voids(None, "voids").is_err());
        let fronts = json!({ "tables": { "fronts": { "columns": ["t", "x"], "rows": [] } } });
        let e = parse_voids(Some(&fronts), "fronts").unwrap_err();
        assert!(
            e.contains("needs columns x, y and area") && e.contains("t, x"),
            "{e}"
        );
    }

    #[test]
    fn spacing_is_the_lattice_spacing() {
        // A 40 x 8 lattice of spacing 0.25 mm with a few holes, shuffled order.
        let h = 2.5e-4;
        let mut points: Vec<(f64, f64)> = (0..320)
            .filter(|i| i % 17 != 3)
            .map(|i| ((i % 40) as f64 * h + 0.5 * h, (i / 40) as f64 * h + 0.5 * h))
            .collect();
        points.reverse();
        let s = particle_spacing(&points).unwrap();
        assert!((s - h).abs() < 1e-9 * h, "{s}");
        // A row of particles; two far apart clusters.
        let row: Vec<(f64, f64)> = (0..10).map(|i| (i as f64 * 0.1, 0.0)).collect();
        assert!((particle_spacing(&row).unwrap() - 0.1).abs() < 1e-12);
        let mut two: Vec<(f64, f64)> = (0..50).map(|i| (i as f64 * 1e-3, 0.0)).collect();
        two.extend((0..50).map(|i| (10.0 + i as f64 * 1e-3, 5.0)));
        assert!((particle_spacing(&two).unwrap() - 1e-3).abs() < 1e-9);
        assert_eq!(particle_spacing(&[(1.0, 1.0)]), None);
        assert_eq!(particle_spacing(&[(1.0, 1.0), (1.0, 1.0)]), None);
    }

    #[test]
    fn frames_count_from_the_end_when_negative() {
        assert_eq!(resolve_frame(None, 3).unwrap(), 2);
        assert_eq!(resolve_frame(Some(-1), 3).unwrap(), 2);
        assert_eq!(resolve_frame(Some(-3), 3).unwrap(), 0);
        assert_eq!(resolve_frame(Some(1), 3).unwrap(), 1);
        let e = resolve_frame(Some(3), 3).unwrap_err().to_string();
        assert!(
            e.contains("out of range") && e.contains("3 frame(s)"),
            "{e}"
        );
        assert!(resolve_frame(Some(-4), 3).is_err());
        assert!(resolve_frame(None, 0).is_err());
    }

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

    #[test]
    fn bounds_cover_the_domain_and_every_square() {
        let b = picture_bounds(&[(0.5, 0.5)], Some([0.0, 1.0, 0.0, 2.0]), 0.1).unwrap();
        assert_eq!(b, [0.0, 1.0, 0.0, 2.0]);
        let b = picture_bounds(&[(0.0, 0.0), (1.0, 0.5)], None, 0.2).unwrap();
        assert_eq!(b, [-0.1, 1.1, -0.1, 0.6]);
        // A line of particles gets some height.
        let b = picture_bounds(&[(0.0, 0.0), (1.0, 0.0)], None, 0.0).unwrap();
        assert!(b[3] - b[2] > 0.05, "{b:?}");
        assert_eq!(picture_bounds(&[], None, 0.0), None);
    }
}
