//! Which two axes a picture draws and which particles it keeps: a 2D store as it is; a 3D
//! store seen along one axis (`--plane`), all of it or a slab of it (`--slab`), nearer
//! particles drawn over farther ones.

use crate::exit_status::input_error;

/// Axis names, by index.
const AXES: [&str; 3] = ["x", "y", "z"];

/// The view of one picture.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct View {
    /// The axes drawn across and up.
    pub(super) axes: [usize; 2],
    /// The axis looked along (3D only).
    pub(super) depth: Option<usize>,
    /// Keep only particles whose depth coordinate lies in `[lo, hi]`, m.
    pub(super) slab: Option<(f64, f64)>,
}

impl View {
    /// The view of `plane` (`xy`, `xz` or `yz`; default `xy`) and `slab` (`LO:HI` in m) for
    /// a store of dimension `dim`; a 2D store takes neither but `xy`.
    pub(super) fn parse(
        plane: Option<&str>,
        slab: Option<&str>,
        dim: usize,
    ) -> anyhow::Result<Self> {
        let axes = match plane.unwrap_or("xy") {
            "xy" => [0, 1],
            "xz" => [0, 2],
            "yz" => [1, 2],
            other => {
                return Err(input_error!(
                    "--plane `{other}`: give the two axes drawn, one of xy, xz, yz"
                ));
            }
        };
        if dim == 2 {
            if axes != [0, 1] {
                return Err(input_error!(
                    "--plane {}: a 2D store has only the xy plane",
                    plane.unwrap_or_default()
                ));
            }
            if slab.is_some() {
                return Err(input_error!(
                    "--slab: a 2D store has no depth to cut; draw it without --slab"
                ));
            }
            return Ok(View {
                axes,
                depth: None,
                slab: None,
            });
        }
        if dim != 3 {
            return Err(input_error!(
                "render draws 2D and 3D stores; this one is {dim}D"
            ));
        }
        let depth = 3 - axes[0] - axes[1];
        let slab = match slab {
            None => None,
            Some(text) => Some(parse_slab(text, AXES[depth])?),
        };
        Ok(View {
            axes,
            depth: Some(depth),
            slab,
        })
    }

    /// Name of axis `i` of the picture (0 across, 1 up).
    pub(super) fn axis_name(&self, i: usize) -> &'static str {
        AXES[self.axes[i]]
    }

    /// The picture's points (drawn in this order, farthest first) and the index of each
    /// particle drawn, from `positions` (`dim` numbers per particle) and `keep` (whether a
    /// particle is in the run at all). Particles with a non-finite coordinate are left out.
    pub(super) fn project(
        &self,
        positions: &[f64],
        dim: usize,
        keep: impl Fn(usize) -> bool,
    ) -> (Vec<(f64, f64)>, Vec<usize>) {
        let n = positions.len() / dim;
        let mut drawn: Vec<(f64, usize)> = Vec::with_capacity(n);
        for p in 0..n {
            let x = &positions[dim * p..dim * (p + 1)];
            if !x.iter().all(|v| v.is_finite()) || !keep(p) {
                continue;
            }
            let depth = self.depth.map_or(0.0, |d| x[d]);
            if let Some((lo, hi)) = self.slab
                && !(lo..=hi).contains(&depth)
            {
                continue;
            }
            drawn.push((depth, p));
        }
        // Seen from the positive end of the depth axis: the largest depth is drawn last (a
        // stable sort: ties keep the particles' order). A 2D store keeps its order.
        if self.depth.is_some() {
            drawn.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        let points = drawn
            .iter()
            .map(|&(_, p)| {
                let x = &positions[dim * p..dim * (p + 1)];
                (x[self.axes[0]], x[self.axes[1]])
            })
            .collect();
        (points, drawn.into_iter().map(|(_, p)| p).collect())
    }

    /// A title suffix naming the view of a 3D store ("seen along z, 0.2 ≤ z ≤ 0.4 mm").
    pub(super) fn caption(&self) -> Option<String> {
        let d = AXES[self.depth?];
        Some(match self.slab {
            None => format!("seen along {d}"),
            Some((lo, hi)) => format!(
                "{d} from {} to {} m",
                super::labels::short(lo),
                super::labels::short(hi)
            ),
        })
    }
}

/// `LO:HI` in metres, LO < HI, both finite.
fn parse_slab(text: &str, axis: &str) -> anyhow::Result<(f64, f64)> {
    let bad = || {
        input_error!(
            "--slab `{text}`: give the range of {axis} to keep as LO:HI in m, LO below HI (e.g. 0.0002:0.0004)"
        )
    };
    let (lo, hi) = text.split_once(':').ok_or_else(bad)?;
    let lo: f64 = lo.trim().parse().map_err(|_| bad())?;
    let hi: f64 = hi.trim().parse().map_err(|_| bad())?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(bad());
    }
    Ok((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_pick_axes_and_slabs_and_refuse_what_a_store_lacks() {
        let v = View::parse(None, None, 2).unwrap();
        assert_eq!((v.axes, v.depth, v.slab), ([0, 1], None, None));
        let v = View::parse(Some("xz"), Some("0.1:0.2"), 3).unwrap();
        assert_eq!(
            (v.axes, v.depth, v.slab),
            ([0, 2], Some(1), Some((0.1, 0.2)))
        );
        assert_eq!(v.axis_name(1), "z");
        let e = |p: Option<&str>, s: Option<&str>, d| View::parse(p, s, d).unwrap_err().to_string();
        assert!(e(Some("xz"), None, 2).contains("only the xy plane"));
        assert!(e(None, Some("0:1"), 2).contains("no depth"));
        assert!(e(Some("zx"), None, 3).contains("one of xy, xz, yz"));
        for s in ["1:0", "a:b", "0.1", "0:inf", "1:1"] {
            assert!(e(None, Some(s), 3).contains("LO:HI"), "{s}");
        }
    }

    #[test]
    fn projection_keeps_the_slab_and_draws_the_nearest_last() {
        // Three particles along z at one (x, y), one outside the slab, one not in the run.
        let positions = [
            1.0,
            2.0,
            0.3, //
            1.0,
            2.0,
            0.1, //
            5.0,
            6.0,
            0.2, //
            7.0,
            8.0,
            0.9, //
            f64::NAN,
            0.0,
            0.0,
        ];
        let v = View::parse(None, Some("0.0:0.5"), 3).unwrap();
        let (points, index) = v.project(&positions, 3, |p| p != 2);
        assert_eq!(index, vec![1, 0]);
        assert_eq!(points, vec![(1.0, 2.0), (1.0, 2.0)]);
        // Seen along x: depth is x, ties in submission order.
        let v = View::parse(Some("yz"), None, 3).unwrap();
        let (points, index) = v.project(&positions, 3, |_| true);
        assert_eq!(index, vec![0, 1, 2, 3]);
        assert_eq!(points[3], (8.0, 0.9));
    }
}
