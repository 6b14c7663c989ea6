//! Singular curves for drawing: where a machine's special poses lie on the bed, as polylines a map draws over its
//! cells ([`crate::workspace::SingularCurve`]). A machine gives them through [`crate::Kinematics::singular_curves`];
//! the two shapes they take are here:
//! a circle (a side stretched straight or folded lies at a fixed distance from its joint), kept where the pose
//! exists, and the boundary between two regions (the five-bar's distal links pass through in line exactly where
//! the configured assembly stops existing), traced by marching squares with every crossing found by bisection.

use std::collections::HashMap;

use crate::workspace::Bounds;
#[cfg(test)]
use crate::workspace::SingularCurve;

/// A crossing is located to this distance along its grid edge (mm).
pub const CROSSING_TOLERANCE: f64 = 1e-9;

fn inside(bounds: &Bounds, p: [f64; 2]) -> bool {
    (bounds.x_min..=bounds.x_max).contains(&p[0]) && (bounds.y_min..=bounds.y_max).contains(&p[1])
}

/// The circle about `centre` of `radius`, sampled with chords of at most `spacing` mm, kept inside `bounds` where
/// `keep` holds: one piece per run of kept samples (a closed circle ends where it began).
pub fn circle_pieces(
    centre: [f64; 2],
    radius: f64,
    bounds: &Bounds,
    spacing: f64,
    keep: impl Fn([f64; 2]) -> bool,
) -> Vec<Vec<[f64; 2]>> {
    if !(radius > 0.0 && spacing > 0.0 && radius.is_finite()) {
        return Vec::new();
    }
    let count = ((std::f64::consts::TAU * radius / spacing).ceil() as usize).clamp(16, 1 << 20);
    let mut pieces: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut current: Vec<[f64; 2]> = Vec::new();
    for i in 0..=count {
        // The last sample is the first again, exactly: a whole circle closes.
        let a = std::f64::consts::TAU * (i % count) as f64 / count as f64;
        let p = [centre[0] + radius * a.cos(), centre[1] + radius * a.sin()];
        if inside(bounds, p) && keep(p) {
            current.push(p);
        } else if !current.is_empty() {
            pieces.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        // The last run meets the first where the circle closes.
        match pieces.first_mut() {
            Some(first) if first.first() == Some(&[centre[0] + radius, centre[1]]) => {
                current.extend(first.drain(1..));
                *first = current;
            }
            _ => pieces.push(current),
        }
    }
    pieces.retain(|piece| piece.len() >= 2);
    pieces
}

/// A grid edge: its lower or left node and whether it runs along x.
type EdgeKey = (usize, usize, bool);

/// The boundary between the points where `side` is `Some(true)` and those where it is `Some(false)` (`None`: neither,
/// no boundary drawn there), over `bounds` on a grid of `spacing` mm: every crossing of a grid edge found by
/// bisection to [`CROSSING_TOLERANCE`], joined into polylines. A boundary that turns back within one grid cell may
/// be missed: the caller picks a spacing finer than the curve's features.
pub fn boundary_pieces(
    bounds: &Bounds,
    spacing: f64,
    side: impl Fn([f64; 2]) -> Option<bool>,
) -> Vec<Vec<[f64; 2]>> {
    let Some(grid) = Grid::new(bounds, spacing) else {
        return Vec::new();
    };
    let nodes: Vec<Option<bool>> = (0..=grid.ny)
        .flat_map(|iy| (0..=grid.nx).map(move |ix| (ix, iy)))
        .map(|(ix, iy)| side(grid.node(ix, iy)))
        .collect();
    let value = |ix: usize, iy: usize| nodes[iy * (grid.nx + 1) + ix];
    let mut crossings: HashMap<EdgeKey, [f64; 2]> = HashMap::new();
    let mut segments: Vec<[EdgeKey; 2]> = Vec::new();
    for iy in 0..grid.ny {
        for ix in 0..grid.nx {
            let edges = [
                (ix, iy, true),
                (ix + 1, iy, false),
                (ix, iy + 1, true),
                (ix, iy, false),
            ];
            let crossed: Vec<EdgeKey> = edges
                .into_iter()
                .filter(|&(ex, ey, along_x)| {
                    let (fx, fy) = if along_x { (ex + 1, ey) } else { (ex, ey + 1) };
                    matches!((value(ex, ey), value(fx, fy)), (Some(a), Some(b)) if a != b)
                })
                .collect();
            for &key in &crossed {
                crossings
                    .entry(key)
                    .or_insert_with(|| grid.crossing(key, &side));
            }
            segments.extend(pair_crossings(&crossed, &grid, (ix, iy), &side));
        }
    }
    chain(&segments, &crossings)
}

/// A cell's crossings joined in pairs: two make one segment; four (a saddle) are paired so that the corners on the
/// centre's side stay joined through it.
fn pair_crossings(
    crossed: &[EdgeKey],
    grid: &Grid,
    (ix, iy): (usize, usize),
    side: &impl Fn([f64; 2]) -> Option<bool>,
) -> Vec<[EdgeKey; 2]> {
    match crossed {
        [a, b] => vec![[*a, *b]],
        [bottom, right, top, left] => {
            let centre = grid.node_f(ix as f64 + 0.5, iy as f64 + 0.5);
            let corner = side(grid.node(ix, iy));
            // The lower left corner cut off alone when the centre is on the other side.
            if side(centre) == corner {
                vec![[*bottom, *right], [*top, *left]]
            } else {
                vec![[*left, *bottom], [*right, *top]]
            }
        }
        _ => Vec::new(),
    }
}

/// The segments (pairs of crossed edges) joined where they share an edge.
fn chain(segments: &[[EdgeKey; 2]], crossings: &HashMap<EdgeKey, [f64; 2]>) -> Vec<Vec<[f64; 2]>> {
    let mut at: HashMap<EdgeKey, Vec<usize>> = HashMap::new();
    for (i, [a, b]) in segments.iter().enumerate() {
        at.entry(*a).or_default().push(i);
        at.entry(*b).or_default().push(i);
    }
    let mut used = vec![false; segments.len()];
    let mut pieces = Vec::new();
    // Open chains start at an edge only one segment touches; what is left are closed loops.
    let ends: Vec<usize> = (0..segments.len())
        .filter(|&i| segments[i].iter().any(|k| at[k].len() == 1))
        .collect();
    for start in ends.into_iter().chain(0..segments.len()) {
        if used[start] {
            continue;
        }
        let [a, b] = segments[start];
        let first = if at[&a].len() == 1 { a } else { b };
        let mut keys = vec![first];
        let (mut current, mut edge) = (start, first);
        loop {
            used[current] = true;
            let [a, b] = segments[current];
            edge = if a == edge { b } else { a };
            keys.push(edge);
            match at[&edge].iter().find(|&&s| !used[s]) {
                Some(&next) => current = next,
                None => break,
            }
        }
        pieces.push(keys.iter().map(|k| crossings[k]).collect());
    }
    pieces
}

/// The marching grid over an area.
struct Grid {
    origin: [f64; 2],
    spacing: f64,
    nx: usize,
    ny: usize,
}

impl Grid {
    /// At most 4,000 nodes a side: a finer spacing over a larger area is coarsened.
    fn new(bounds: &Bounds, spacing: f64) -> Option<Grid> {
        let (w, h) = (bounds.x_max - bounds.x_min, bounds.y_max - bounds.y_min);
        if !(spacing > 0.0 && w > 0.0 && h > 0.0 && w.is_finite() && h.is_finite()) {
            return None;
        }
        let spacing = spacing.max(w.max(h) / 4000.0);
        Some(Grid {
            origin: [bounds.x_min, bounds.y_min],
            spacing,
            nx: (w / spacing).ceil() as usize,
            ny: (h / spacing).ceil() as usize,
        })
    }

    fn node(&self, ix: usize, iy: usize) -> [f64; 2] {
        self.node_f(ix as f64, iy as f64)
    }

    fn node_f(&self, ix: f64, iy: f64) -> [f64; 2] {
        [
            self.origin[0] + ix * self.spacing,
            self.origin[1] + iy * self.spacing,
        ]
    }

    /// Where `side` changes along the edge `key`, by bisection.
    fn crossing(&self, key: EdgeKey, side: &impl Fn([f64; 2]) -> Option<bool>) -> [f64; 2] {
        let (ix, iy, along_x) = key;
        let a = self.node(ix, iy);
        let b = if along_x {
            self.node(ix + 1, iy)
        } else {
            self.node(ix, iy + 1)
        };
        let at = |t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        let start = side(a);
        let (mut lo, mut hi) = (0.0, 1.0);
        while (hi - lo) * self.spacing > CROSSING_TOLERANCE {
            let mid = 0.5 * (lo + hi);
            // An undefined point between the ends counts as the far side: the crossing stays on the edge.
            if side(at(mid)) == start {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        at(0.5 * (lo + hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(half: f64) -> Bounds {
        Bounds {
            x_min: -half,
            x_max: half,
            y_min: -half,
            y_max: half,
        }
    }

    #[test]
    fn the_boundary_of_a_disc_is_its_circle() {
        let r = 7.3;
        let pieces = boundary_pieces(&square(10.0), 0.5, |p| Some(p[0].hypot(p[1]) < r));
        assert_eq!(pieces.len(), 1, "one closed loop");
        let loop_ = &pieces[0];
        assert_eq!(loop_.first(), loop_.last(), "closed");
        for p in loop_ {
            assert!((p[0].hypot(p[1]) - r).abs() < 1e-8, "{p:?}");
        }
        let length: f64 = SingularCurve {
            label: "disc",
            pieces: pieces.clone(),
        }
        .length();
        assert!(
            (length - std::f64::consts::TAU * r).abs() < 0.01 * r,
            "{length}"
        );
    }

    #[test]
    fn a_line_across_the_area_is_one_open_piece_and_undefined_points_cut_it() {
        let line = |p: [f64; 2]| Some(p[1] > 0.3 * p[0] + 1.0);
        let pieces = boundary_pieces(&square(10.0), 0.7, line);
        assert_eq!(pieces.len(), 1);
        for p in &pieces[0] {
            assert!((p[1] - 0.3 * p[0] - 1.0).abs() < 1e-8, "{p:?}");
        }
        let cut = |p: [f64; 2]| (p[0].abs() > 2.0).then(|| p[1] > 0.3 * p[0] + 1.0);
        assert_eq!(boundary_pieces(&square(10.0), 0.7, cut).len(), 2);
    }

    #[test]
    fn a_circle_is_kept_where_asked_and_closes_where_it_began() {
        let whole = circle_pieces([1.0, 2.0], 5.0, &square(20.0), 0.1, |_| true);
        assert_eq!(whole.len(), 1);
        assert_eq!(whole[0].first(), whole[0].last());
        let upper = circle_pieces([0.0, 0.0], 5.0, &square(20.0), 0.1, |p| p[1] > 1.0);
        assert_eq!(upper.len(), 1);
        assert!(upper[0].iter().all(|p| p[1] > 1.0));
        // The right half crosses the circle's start (angle 0): still one piece.
        let right = circle_pieces([0.0, 0.0], 5.0, &square(20.0), 0.1, |p| p[0] > 0.5);
        assert_eq!(right.len(), 1);
        assert!(
            right[0]
                .windows(2)
                .all(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) < 0.11)
        );
    }
}
