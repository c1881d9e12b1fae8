//! The picture of a stability map (PNG): a row per scheme, a column per CFL factor, each
//! cell coloured by how the run ended (green shades by the size of the energy error where
//! it finished) with the energy error written in it; drawn with plotters and the bundled
//! font.

use crate::plot::register_font;
use crate::stability_map::{CaseMap, MapCell, MapOutcome};
use anyhow::{Context, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

const LABEL_WIDTH: i32 = 170;
const CELL_WIDTH: i32 = 84;
const ROW_HEIGHT: i32 = 22;
const TOP: i32 = 92;
const LEGEND_HEIGHT: i32 = 96;

/// Finished with |energy error| below each bound, darkest first; the last has no bound.
const FINISHED: [(f64, RGBColor); 4] = [
    (1e-3, RGBColor(26, 152, 80)),
    (1e-2, RGBColor(102, 189, 99)),
    (1e-1, RGBColor(166, 217, 106)),
    (f64::INFINITY, RGBColor(217, 239, 139)),
];
const STOPPED: RGBColor = RGBColor(253, 174, 97);
const BLOW_UP: RGBColor = RGBColor(215, 48, 39);
const REFUSED: RGBColor = RGBColor(200, 200, 200);
const ERROR: RGBColor = RGBColor(118, 42, 131);

/// The colour of a cell.
fn colour(cell: &MapCell) -> RGBColor {
    match cell.outcome {
        MapOutcome::Finished => {
            let e = cell.energy_drift.unwrap_or(f64::INFINITY).abs();
            FINISHED
                .iter()
                .find(|(bound, _)| e < *bound)
                .map_or(FINISHED[3].1, |(_, c)| *c)
        }
        MapOutcome::Stopped => STOPPED,
        MapOutcome::BlowUp => BLOW_UP,
        MapOutcome::Refused => REFUSED,
        MapOutcome::Error => ERROR,
    }
}

/// The text of a cell: the energy error where the run ran, else the outcome.
fn text(cell: &MapCell) -> String {
    match (cell.outcome, cell.energy_drift) {
        (MapOutcome::Refused | MapOutcome::Error, _) | (_, None) => cell.outcome.name().into(),
        (_, Some(e)) if e.is_finite() => format!("{e:+.1e}"),
        _ => "NaN".into(),
    }
}

/// Width and height of the picture of `map`, pixels.
pub fn size(map: &CaseMap) -> (u32, u32) {
    let w = LABEL_WIDTH + CELL_WIDTH * map.factors.len() as i32 + 20;
    let h = TOP + ROW_HEIGHT * map.rows.len() as i32 + LEGEND_HEIGHT;
    (w.max(960) as u32, h as u32)
}

/// Writes the picture of `map` to `path` (PNG).
pub fn draw(path: &Path, map: &CaseMap) -> anyhow::Result<()> {
    register_font();
    draw_on(BitMapBackend::new(path, size(map)).into_drawing_area(), map)
        .with_context(|| format!("drawing {}", path.display()))
}

fn draw_on<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, map: &CaseMap) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    root.fill(&WHITE).map_err(err)?;
    let left = ("sans-serif", 13).into_font().color(&BLACK);
    let centre = left.pos(Pos::new(HPos::Center, VPos::Center));
    let right = left.pos(Pos::new(HPos::Right, VPos::Center));
    root.draw(&Text::new(
        format!("Stability map: {}", map.case),
        (10, 8),
        ("sans-serif", 22).into_font().color(&BLACK),
    ))
    .map_err(err)?;
    root.draw(&Text::new(map.what.clone(), (10, 38), left.clone()))
        .map_err(err)?;
    root.draw(&Text::new(
        format!(
            "fixed dt = CFL factor × the stable step {:.3e} s; each cell: the energy error (energy drift)",
            map.stable_dt
        ),
        (10, 56),
        left.clone(),
    ))
    .map_err(err)?;
    let header = TOP - ROW_HEIGHT / 2 - 2;
    root.draw(&Text::new(
        "scheme \\ CFL factor",
        (LABEL_WIDTH - 8, header),
        right.clone(),
    ))
    .map_err(err)?;
    for (c, f) in map.factors.iter().enumerate() {
        let x = LABEL_WIDTH + CELL_WIDTH * c as i32 + CELL_WIDTH / 2;
        root.draw(&Text::new(format!("{f}"), (x, header), centre.clone()))
            .map_err(err)?;
    }
    for (r, label) in map.rows.iter().enumerate() {
        let y = TOP + ROW_HEIGHT * r as i32;
        root.draw(&Text::new(
            label.clone(),
            (LABEL_WIDTH - 8, y + ROW_HEIGHT / 2),
            right.clone(),
        ))
        .map_err(err)?;
        for c in 0..map.factors.len() {
            let cell = map.cell(r, c);
            let x = LABEL_WIDTH + CELL_WIDTH * c as i32;
            let fill = colour(cell);
            root.draw(&Rectangle::new(
                [(x, y), (x + CELL_WIDTH, y + ROW_HEIGHT)],
                fill.filled(),
            ))
            .map_err(err)?;
            root.draw(&Rectangle::new(
                [(x, y), (x + CELL_WIDTH, y + ROW_HEIGHT)],
                WHITE.stroke_width(1),
            ))
            .map_err(err)?;
            let ink = if matches!(cell.outcome, MapOutcome::BlowUp | MapOutcome::Error) {
                WHITE
            } else {
                BLACK
            };
            root.draw(&Text::new(
                text(cell),
                (x + CELL_WIDTH / 2, y + ROW_HEIGHT / 2),
                centre.color(&ink),
            ))
            .map_err(err)?;
        }
    }
    let legend_top = TOP + ROW_HEIGHT * map.rows.len() as i32 + 16;
    let entries = [
        (FINISHED[0].1, "finished, |error| < 1e-3"),
        (FINISHED[1].1, "finished, < 1e-2"),
        (FINISHED[2].1, "finished, < 1e-1"),
        (FINISHED[3].1, "finished, >= 1e-1"),
        (STOPPED, "stopped (its own check)"),
        (BLOW_UP, "blow-up (energy grew > 2%, NaN)"),
        (REFUSED, "refused"),
        (ERROR, "error"),
    ];
    for (i, (fill, name)) in entries.iter().enumerate() {
        let x = 10 + 235 * (i as i32 % 4);
        let y = legend_top + 26 * (i as i32 / 4);
        root.draw(&Rectangle::new([(x, y), (x + 18, y + 18)], fill.filled()))
            .map_err(err)?;
        root.draw(&Text::new(
            name.to_string(),
            (x + 24, y + 9),
            left.pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
