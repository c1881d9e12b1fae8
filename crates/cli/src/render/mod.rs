//! `mpm render`: one frame of a result store as a PNG picture of the particles coloured
//! by a field (equal axes, a viridis colour bar), for documentation pictures; a 3D store
//! seen along an axis, whole or a slab of it; optionally with the voids of a table in the
//! store's metrics marked as red circles; a refined run's grid levels outlined.

mod colour;
mod draw;
mod geometry;
mod labels;
mod levels;
mod service;
mod view;
mod voids;

pub(crate) use labels::short;
pub use service::ServiceRenderer;

use crate::exit_status::input_error;
use anyhow::{Context, bail};
use colour::finite_range;
use draw::{Picture, draw};
use geometry::{domain, picture_bounds, spacing_of};
use levels::level_outlines;
use mpm_io::ResultStore;
use serde_json::Value;
use std::path::PathBuf;
use view::View;
use voids::parse_voids;

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
    /// Stage of a staged run's store (default: the last).
    pub stage: Option<String>,
    /// The two axes a 3D store is drawn on (`xy`, `xz`, `yz`; default `xy`).
    pub plane: Option<String>,
    /// `LO:HI`: keep the particles of a 3D store whose third coordinate lies there, m.
    pub slab: Option<String>,
    /// Draw each particle's square at the first frame's spacing deformed by its F.
    pub deformed: bool,
    /// Leave out the outlines of a refined run's grid levels.
    pub hide_levels: bool,
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
    /// Refined grid levels outlined, when the run had some.
    pub levels: Option<usize>,
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
    let store = ResultStore::open_stage(&args.store, args.stage.as_deref())
        .with_context(|| format!("cannot open result store `{}`", args.store.display()))?;
    let dim = store.dimension();
    let view = View::parse(args.plane.as_deref(), args.slab.as_deref(), dim)?;
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
    let n = positions.len() / dim;
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

    // Particles an inlet has not let in yet, or that left through an open face, wait
    // massless where they are (`injected` 0 and −1): not drawn.
    let injected = if fields.iter().any(|f| f == "injected") {
        Some(store.frame("injected", k)?.1)
    } else {
        None
    };
    let in_run = |p: usize| {
        injected
            .as_ref()
            .is_none_or(|s| s.get(p).is_some_and(|v| *v > 0.5))
    };
    let (points, drawn) = view.project(&positions, dim, in_run);
    let scalar: Vec<f64> = drawn
        .iter()
        .map(|&p| values[p * components + args.component])
        .collect();

    let voids = match &args.voids {
        None => None,
        Some(table) => match parse_voids(
            store.metrics(),
            table,
            [view.axis_name(0), view.axis_name(1)],
            dim,
            time,
        ) {
            Ok(t) => {
                if t.skipped > 0 {
                    eprintln!(
                        "warning: {} row(s) of table `{table}` lack a finite centre or size; not drawn",
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
    let mut title = args.title.clone().unwrap_or_else(|| {
        let view = view.caption().map(|c| format!(", {c}")).unwrap_or_default();
        format!("{scene} — {label} at t = {} s{view}", short(time))
    });
    if let Some(v) = &voids {
        let noun = if v.len() == 1 { "void" } else { "voids" };
        title = format!("{title}, {} {noun}", v.len());
    }

    // With --deformed the squares are the particles' domains at the first frame, mapped by F.
    let (spacing, shapes) = if args.deformed {
        let (_, first) = store.frame("x", 0)?;
        (
            spacing_of(&first, dim, &drawn),
            Some(deformed_shapes(
                &store, &fields, k, dim, view.axes, &drawn, n,
            )?),
        )
    } else {
        (spacing_of(&positions, dim, &drawn), None)
    };
    let bounds = picture_bounds(
        &points,
        domain(attributes, view.axes),
        spacing.unwrap_or(0.0),
    )
    .context("nothing to draw: no particle positions and no domain in the store")?;
    let spacing = spacing.unwrap_or_else(|| {
        let (w, h) = (bounds[1] - bounds[0], bounds[3] - bounds[2]);
        (w * h / points.len().max(1) as f64).sqrt()
    });
    let range = finite_range(&scalar);
    let outlines = if args.hide_levels {
        None
    } else {
        match level_outlines(attributes.get("scene"), dim, view.axes, view.slab, bounds) {
            Ok(o) => o,
            Err(message) => {
                eprintln!("warning: {message}; drawing without the grid levels");
                None
            }
        }
    };
    if let Some(o) = &outlines {
        let noun = if o.len() == 1 { "level" } else { "levels" };
        title = format!("{title}, {} refined {noun} outlined", o.len());
    }

    std::fs::File::create(&args.out)
        .with_context(|| format!("cannot write `{}`", args.out.display()))?;
    let picture = Picture {
        points: &points,
        values: &scalar,
        range,
        spacing,
        shapes: shapes.as_deref(),
        bounds,
        title: &title,
        label: &label,
        voids: voids.as_deref().unwrap_or(&[]),
        levels: outlines.as_deref().unwrap_or(&[]),
        axes: [view.axis_name(0), view.axis_name(1)],
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
        levels: outlines.map(|o| o.len()),
    })
}

/// The in-picture 2×2 block of F (row-major, the drawn axes) of every drawn particle, for
/// `--deformed`; the store must hold `F`.
fn deformed_shapes(
    store: &ResultStore,
    fields: &[String],
    k: u64,
    dim: usize,
    axes: [usize; 2],
    drawn: &[usize],
    n: usize,
) -> anyhow::Result<Vec<[f64; 4]>> {
    if !fields.iter().any(|f| f == "F") {
        return Err(input_error!(
            "--deformed draws each particle deformed by F, which this store does not hold; \
             add \"F\" to output.fields (available fields: {})",
            fields.join(", ")
        ));
    }
    let (_, f) = store.frame("F", k)?;
    if f.len() != n * dim * dim {
        bail!("field `F` does not hold {dim}×{dim} numbers for each of the {n} particles");
    }
    let [a, b] = axes;
    Ok(drawn
        .iter()
        .map(|&p| {
            let m = &f[p * dim * dim..(p + 1) * dim * dim];
            [
                m[a * dim + a],
                m[a * dim + b],
                m[b * dim + a],
                m[b * dim + b],
            ]
        })
        .collect())
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
