//! Damage figures a run (and each stage of a staged run) reports at its end, per material
//! whose law keeps a `damage` state field (`johnson_cook`, `phase_mixture` with damage):
//! the largest damage, the particles that failed (damage 1) with their current volume, the
//! cracks they make (failed neighbours joined) and the longest crack's length, the most
//! damaged sites (damaged neighbours joined, so a crack's rival that has not failed yet
//! shows), and when and where the first particle failed (`solver/failure_watch.rs` watches
//! for that each step).

use crate::math::{Vector, determinant};
use crate::particles::{MaterialGroup, Particles};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};

/// One material's damage at a run's (stage's) end.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DamageFigures {
    /// Largest damage of its particles, in [0, 1].
    pub peak: f64,
    /// Particles at damage 1 (failed: they carry no tension).
    pub failed_particles: usize,
    /// Current volume of the failed particles, m³ (m² per unit thickness in 2D).
    pub failed_volume: f64,
    /// Cracks: groups of failed particles, each joined through neighbours closer than
    /// [`CRACK_LINK`] particle spacings.
    #[serde(default)]
    pub cracks: usize,
    /// The longest crack's length, m: its failed particles' extent along their principal
    /// direction plus one particle spacing (0 without failed particles). In 3D a crack is
    /// a surface and this is its largest extent.
    #[serde(default)]
    pub crack_length: f64,
    /// The first particle that failed during the run (stage); `None` if none did. A
    /// particle failed before the stage began does not count.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset: Option<FailureOnset>,
    /// The most damaged sites, most damaged first (at most [`SITES_REPORTED`]): groups of
    /// particles at damage [`SITE_DAMAGE`] or more, joined as cracks are. Two stress
    /// raisers that race to crack first both show here, whichever won.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sites: Vec<DamageSite>,
}

/// A damaged site: neighbouring particles at damage [`SITE_DAMAGE`] or more.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DamageSite {
    /// Its largest damage.
    pub peak: f64,
    /// The mean position of its particles, m (z = 0 in 2D).
    pub centre: [f64; 3],
    /// Its particles.
    pub particles: usize,
    /// Those of them that have failed.
    pub failed_particles: usize,
}

/// When and where the first particle of a material failed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FailureOnset {
    /// Simulated time at the end of the step it failed in, s.
    pub time: f64,
    /// Its position then, m (z = 0 in 2D).
    pub position: [f64; 3],
    /// Its index in the output order.
    pub particle: u32,
}

/// Failed particles closer than this many particle spacings belong to one crack.
pub const CRACK_LINK: f64 = 1.5;

/// The damage from which a particle belongs to a damaged site.
pub const SITE_DAMAGE: f64 = 0.5;

/// How many damaged sites a material reports.
pub const SITES_REPORTED: usize = 6;

/// The index of `group`'s one-component `damage` state field, if its law keeps one.
pub fn damage_field(group: &MaterialGroup) -> Option<usize> {
    group
        .material
        .state_fields()
        .iter()
        .position(|f| f.name == "damage" && f.components == 1)
}

/// The damage figures of every material whose law keeps a `damage` field; materials
/// without one are left out. `onset` is left `None` (the run loop's watch fills it).
pub fn damage_figures<const D: usize>(particles: &Particles<D>) -> BTreeMap<String, DamageFigures> {
    let mut out = BTreeMap::new();
    let mut failed: BTreeMap<String, Marked<D>> = BTreeMap::new();
    let mut damaged: BTreeMap<String, Marked<D>> = BTreeMap::new();
    for group in &particles.groups {
        let Some(field) = damage_field(group) else {
            continue;
        };
        let entry: &mut DamageFigures = out.entry(group.name.clone()).or_default();
        let failed = failed.entry(group.name.clone()).or_default();
        let damaged = damaged.entry(group.name.clone()).or_default();
        for (k, &d) in group.state[field].iter().enumerate() {
            entry.peak = entry.peak.max(d);
            let p = group.range.start + k;
            if d >= SITE_DAMAGE {
                damaged.push(particles, p, d);
            }
            if d >= 1.0 {
                entry.failed_particles += 1;
                entry.failed_volume +=
                    determinant(&particles.deformation_gradient[p]) * particles.volume0[p];
                failed.push(particles, p, d);
            }
        }
    }
    for (name, failed) in failed {
        if let (Some(entry), false) = (out.get_mut(&name), failed.points.is_empty()) {
            let (cracks, length) = cracks(&failed.points, failed.spacing());
            entry.cracks = cracks;
            entry.crack_length = length;
        }
    }
    for (name, damaged) in damaged {
        if let Some(entry) = out.get_mut(&name) {
            entry.sites = sites(&damaged);
        }
    }
    out
}

/// Particles picked out of a material: where they are, their damage and the sum of their
/// spacings (the cube or square root of their initial volume).
#[derive(Default)]
struct Marked<const D: usize> {
    points: Vec<Vector<D>>,
    damage: Vec<f64>,
    spacings: f64,
}

impl<const D: usize> Marked<D> {
    fn push(&mut self, particles: &Particles<D>, p: usize, damage: f64) {
        self.points.push(particles.position[p]);
        self.damage.push(damage);
        self.spacings += particles.volume0[p].abs().powf(1.0 / D as f64);
    }

    /// Their mean spacing.
    fn spacing(&self) -> f64 {
        self.spacings / self.points.len().max(1) as f64
    }
}

/// The [`SITES_REPORTED`] most damaged sites among `damaged`: most damaged first, then
/// the one with more failed particles, then more particles.
fn sites<const D: usize>(damaged: &Marked<D>) -> Vec<DamageSite> {
    let mut sites: Vec<DamageSite> = linked_groups(&damaged.points, damaged.spacing())
        .into_iter()
        .map(|members| {
            let mut centre = [0.0; 3];
            for &i in &members {
                for (a, v) in damaged.points[i].iter().enumerate() {
                    centre[a] += v / members.len() as f64;
                }
            }
            DamageSite {
                peak: members
                    .iter()
                    .map(|&i| damaged.damage[i])
                    .fold(0.0, f64::max),
                centre,
                particles: members.len(),
                failed_particles: members
                    .iter()
                    .filter(|&&i| damaged.damage[i] >= 1.0)
                    .count(),
            }
        })
        .collect();
    sites.sort_by(|a, b| {
        b.peak
            .total_cmp(&a.peak)
            .then(b.failed_particles.cmp(&a.failed_particles))
            .then(b.particles.cmp(&a.particles))
    });
    sites.truncate(SITES_REPORTED);
    sites
}

/// The cracks among the failed particles at `points`, `spacing` apart on average: how
/// many, and the longest one's length.
fn cracks<const D: usize>(points: &[Vector<D>], spacing: f64) -> (usize, f64) {
    let groups = linked_groups(points, spacing);
    let longest = groups
        .iter()
        .map(|members| {
            let points: Vec<Vector<D>> = members.iter().map(|&i| points[i]).collect();
            principal_extent(&points) + spacing
        })
        .fold(0.0, f64::max);
    (groups.len(), longest)
}

/// `points` joined into groups through neighbours closer than [`CRACK_LINK`] × `spacing`,
/// each group its members' indices in increasing order, the groups in the order of their
/// first member. Neighbours are found through a hash of cells one link long, so the cost
/// is linear in the points. A spacing that is not positive and finite leaves every point
/// on its own.
fn linked_groups<const D: usize>(points: &[Vector<D>], spacing: f64) -> Vec<Vec<usize>> {
    let link = CRACK_LINK * spacing;
    if !(link > 0.0 && link.is_finite()) {
        return (0..points.len()).map(|i| vec![i]).collect();
    }
    let cell_of = |x: &Vector<D>| -> [i64; 3] {
        let mut c = [0i64; 3];
        for (a, v) in x.iter().enumerate() {
            c[a] = (v / link).floor() as i64;
        }
        c
    };
    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, x) in points.iter().enumerate() {
        cells.entry(cell_of(x)).or_default().push(i);
    }
    let mut parent: Vec<usize> = (0..points.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let reach = if D == 3 { 1 } else { 0 };
    for (i, x) in points.iter().enumerate() {
        let c = cell_of(x);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -reach..=reach {
                    let Some(others) = cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &j in others {
                        if j > i && (points[j] - x).norm() <= link {
                            let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                            parent[a.max(b)] = a.min(b);
                        }
                    }
                }
            }
        }
    }
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for i in 0..points.len() {
        let r = root(&mut parent, i);
        members.entry(r).or_default().push(i);
    }
    members.into_values().collect()
}

/// The extent of `points` along their principal direction (the covariance's largest
/// eigenvector, by power iteration from the longest axis of their bounding box).
fn principal_extent<const D: usize>(points: &[Vector<D>]) -> f64 {
    let n = points.len() as f64;
    let centre = points.iter().fold(Vector::<D>::zeros(), |s, x| s + x) / n;
    let mut covariance = crate::math::Matrix::<D>::zeros();
    for x in points {
        let d = x - centre;
        covariance += d * d.transpose();
    }
    let mut low = points[0];
    let mut high = points[0];
    for x in points {
        low = low.inf(x);
        high = high.sup(x);
    }
    let mut direction = Vector::<D>::zeros();
    direction[(high - low).imax()] = 1.0;
    for _ in 0..50 {
        let next = covariance * direction;
        let norm = next.norm();
        if norm <= 0.0 || !norm.is_finite() {
            break;
        }
        direction = next / norm;
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in points {
        let s = (x - centre).dot(&direction);
        lo = lo.min(s);
        hi = hi.max(s);
    }
    hi - lo
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(xy: &[(f64, f64)]) -> Vec<Vector<2>> {
        xy.iter().map(|&(x, y)| Vector::<2>::new(x, y)).collect()
    }

    #[test]
    fn a_line_of_points_extends_along_its_line() {
        // Ten points along a 30° line, 1 apart: extent 9 whatever the bounding box says.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let line: Vec<(f64, f64)> = (0..10).map(|i| (i as f64 * c, i as f64 * s)).collect();
        assert!((principal_extent(&points(&line)) - 9.0).abs() < 1e-9);
        assert_eq!(principal_extent(&points(&[(2.0, 3.0)])), 0.0);
    }

    #[test]
    fn failed_neighbours_join_into_cracks_and_the_longest_is_measured() {
        // A crack of 6 particles along x (spacing 1), a diagonal pair 1.4 apart (linked
        // below 1.5 spacings) and a lone particle 2 away from both.
        let mut xy: Vec<(f64, f64)> = (0..6).map(|i| (i as f64, 0.0)).collect();
        xy.extend([(20.0, 20.0), (21.0, 21.0), (40.0, 0.0)]);
        let (count, length) = cracks(&points(&xy), 1.0);
        assert_eq!(count, 3);
        assert!((length - 6.0).abs() < 1e-9, "{length}");
        // Two particles 1.6 spacings apart are two cracks of one spacing each.
        assert_eq!(cracks(&points(&[(0.0, 0.0), (1.6, 0.0)]), 1.0), (2, 1.0));
        assert_eq!(cracks::<2>(&[], 1.0), (0, 0.0));
    }

    #[test]
    fn damaged_sites_are_ranked_by_their_peak_and_keep_a_rival_that_has_not_failed() {
        // A crack of three failed particles with a damaged neighbour; a rival of two at
        // 0.7 and 0.6 far away; a lone particle at 0.55; then lone ones at 0.5, one more
        // than the sites reported, so that the last is left out.
        let mut xy = vec![
            (0.0, 0.0),
            (1.0, 0.0),
            (2.0, 0.0),
            (3.0, 0.0),
            (50.0, 50.0),
            (51.0, 50.0),
            (-40.0, 0.0),
        ];
        let mut damage = vec![1.0, 1.0, 0.8, 1.0, 0.6, 0.7, 0.55];
        for k in 0..SITES_REPORTED - 2 {
            xy.push((100.0 + 10.0 * k as f64, 80.0));
            damage.push(0.5);
        }
        let marked = Marked::<2> {
            spacings: xy.len() as f64,
            points: points(&xy),
            damage,
        };
        let sites = sites(&marked);
        assert_eq!(sites.len(), SITES_REPORTED);
        assert_eq!((sites[0].peak, sites[0].particles), (1.0, 4));
        assert_eq!(sites[0].failed_particles, 3);
        assert_eq!(sites[0].centre, [1.5, 0.0, 0.0]);
        assert_eq!((sites[1].peak, sites[1].particles), (0.7, 2));
        assert_eq!(sites[1].centre, [50.5, 50.0, 0.0]);
        assert_eq!((sites[2].peak, sites[2].failed_particles), (0.55, 0));
        assert_eq!(sites[SITES_REPORTED - 1].peak, 0.5);
    }
}
