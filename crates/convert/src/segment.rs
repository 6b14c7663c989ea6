//! Cutting one path into pieces that are straight in output-axis (motor) space.
//!
//! Adaptive rule: a piece `[s0, s1]` is accepted when the toolhead, moved linearly in motor space between
//! the piece's end points, stays within the target of the intended sub-path. For a straight line on polar
//! axes the deviation has a closed-form upper bound ([`crate::bound`]), a guarantee that needs no forward
//! kinematics, so those pieces may use the whole tolerance. Elsewhere (SCARA, arcs, corrected Cartesian)
//! the deviation is measured by forward kinematics at three interior points (the error of a short
//! motor-space chord is close to a parabola `u(1−u)·k`, so these find its peak within a few percent; the
//! target keeps a margin below the tolerance for that), and a piece may not turn a rotary axis by more
//! than [`MAX_ANGLE_STEP`], so the parabola model holds. Lengths follow the chord-error law `e ∝ h²`:
//! after each trial the next length is `h·√(target/e)`, and each piece is as long as the target allows,
//! so a move needs as few pieces as its curvature in motor space demands: long where the map is nearly
//! linear, short near the polar centre or a singular SCARA pose, without a fixed number per second.

use kinematics::{MotorUnit, ReachError};

use crate::axes::AxisMap;
use crate::bound::polar_line_bound;
use crate::path::Path;

/// Largest turn of a rotary output axis in one piece (rad).
pub const MAX_ANGLE_STEP: f64 = std::f64::consts::FRAC_PI_4;
/// Interior points where a piece's deviation is evaluated: the middle first, then the quarters.
const PROBES: [f64; 3] = [0.5, 0.25, 0.75];
/// A piece whose middle deviates less than this share of the target needs no quarter probes: in the
/// parabola regime the quarters deviate ¾ as much as the middle.
const MIDDLE_ONLY: f64 = 0.25;
/// A piece that passes with less than this share of its budget is kept in hand while a longer one is
/// tried (by the h² rule, a piece at this load is within 5% of the longest allowed).
const STRETCH: f64 = 0.9;
/// A piece shorter than this (mm) that still misses the target means the map is not smooth here.
const MIN_PIECE_MM: f64 = 1e-9;

/// A written point: path parameter and output axes (mm / rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Breakpoint {
    pub s: f64,
    pub axes: [f64; 2],
}

/// Why a path could not be cut.
#[derive(Debug, Clone, PartialEq)]
pub enum CutError {
    Reach(ReachError),
    /// The chord error stays above the target even for tiny pieces, near path parameter `s`.
    NoConvergence {
        s: f64,
    },
}

impl From<ReachError> for CutError {
    fn from(e: ReachError) -> Self {
        CutError::Reach(e)
    }
}

/// The largest deviation found at the probe points of the motor-space chord `a0 → a1` over `[s0, s1]`.
pub fn chord_deviation(
    path: &Path,
    map: &AxisMap,
    (s0, a0): (f64, [f64; 2]),
    (s1, a1): (f64, [f64; 2]),
    probes: &[f64],
) -> Result<f64, ReachError> {
    let z0 = path.point(s0)[2];
    let z1 = path.point(s1)[2];
    let part = path.part(s0, s1);
    let mut worst = 0.0f64;
    for &u in probes {
        let a = [a0[0] + (a1[0] - a0[0]) * u, a0[1] + (a1[1] - a0[1]) * u];
        let q = map.from_axes(a, z0 + (z1 - z0) * u)?;
        worst = worst.max(part.distance(q));
    }
    Ok(worst)
}

/// Allowed deviation of a piece, per way of measuring it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    /// For a guaranteed bound ([`crate::bound`]).
    pub bound: f64,
    /// For the probe estimate, which may miss the true peak by a few percent.
    pub probe: f64,
}

/// Deviation of a trial piece: the middle probe, and the quarter probes unless the middle is far inside the
/// target. A probe where the map fails counts as infinite (the piece is split).
fn probe(
    path: &Path,
    map: &AxisMap,
    from: (f64, [f64; 2]),
    to: (f64, [f64; 2]),
    target: f64,
) -> f64 {
    let middle = chord_deviation(path, map, from, to, &PROBES[..1]).unwrap_or(f64::INFINITY);
    if middle <= target * MIDDLE_ONLY || middle > target {
        return middle;
    }
    let quarters = chord_deviation(path, map, from, to, &PROBES[1..]).unwrap_or(f64::INFINITY);
    middle.max(quarters)
}

/// A trial piece's deviation as a share of what it may have (≤ 1: accepted): the closed-form bound for a
/// straight line on polar axes, the probes otherwise. The probes also need the piece to turn a rotary axis
/// by at most [`MAX_ANGLE_STEP`]; a piece turning `k` times that counts as loaded `k²`, so the h² rule cuts
/// it to the allowed turn.
fn load(
    path: &Path,
    map: &AxisMap,
    (s0, p0, a0): (f64, [f64; 3], [f64; 2]),
    (s1, p1, a1): (f64, [f64; 3], [f64; 2]),
    budget: Budget,
) -> f64 {
    if let (Some(polar), Path::Line { .. }) = (map.polar(), path) {
        let ends = (([p0[0], p0[1]], a0), ([p1[0], p1[1]], a1));
        if let Some(bound) = polar_line_bound(polar, ends.0, ends.1) {
            return bound / budget.bound;
        }
    }
    let turn = turn_ratio(a0, a1, map.units().map(|u| u == MotorUnit::Rad));
    if turn > 1.0 + 1e-9 {
        return turn * turn;
    }
    probe(path, map, (s0, a0), (s1, a1), budget.probe) / budget.probe
}

/// Adaptive cut of `path` from `(s_start, a_start)` to `s_end`; pushes the end point of every piece.
///
/// Greedy: each piece as long as its budget allows (the h² rule proposes the length, the trial decides),
/// which gives the fewest pieces; a piece that passes with much to spare is kept in hand while a longer one
/// is tried. The whole move is tried first, and the last two pieces share the rest equally.
pub fn cut_adaptive(
    path: &Path,
    map: &AxisMap,
    (s_start, a_start): (f64, [f64; 2]),
    s_end: f64,
    budget: Budget,
    out: &mut Vec<Breakpoint>,
) -> Result<(), CutError> {
    let length = path.length().max(path.xy_length());
    let longest = path.longest_piece();
    let polar = map.polar();
    let (mut s0, mut a0) = (s_start, a_start);
    let mut p0 = path.point(s0);
    let mut h = longest;
    // A piece that passed (and its end point), kept while a longer one is tried.
    let mut in_hand: Option<(Breakpoint, [f64; 3])> = None;
    // A trial of everything left has failed (no more taking a sliver with the piece before it).
    let mut rest_failed = false;
    // Trials on polar axes step the angle from the previous end (no atan2 per trial); the first piece of
    // the move is written with the closed form, so rounding does not accumulate from move to move.
    let settle = |piece: Breakpoint, end: [f64; 3], from: f64| -> Result<Breakpoint, CutError> {
        if polar.is_some() && from == s_start {
            let axes = map.to_axes(end, a_start)?;
            return Ok(Breakpoint { axes, ..piece });
        }
        Ok(piece)
    };
    while s0 < s_end {
        let mut s1 = s0 + last_two(s_end - s0, h.min(longest));
        // Do not leave a sliver at the end, unless the whole rest has failed already: a failed piece must get
        // shorter, or a move ending where the map turns fast (a line passing a µm from the polar centre)
        // would try the same piece forever.
        if s1 >= s_end || ((s_end - s1) * length < 1e-6 && !rest_failed) {
            s1 = s_end;
        }
        let piece = s1 - s0;
        if piece <= 0.0 {
            // Below the resolution of the path parameter: no piece short enough exists here.
            return Err(CutError::NoConvergence { s: s0 });
        }
        let p1 = path.point(s1);
        let trial = match polar {
            Some(polar) => polar.step((p0, a0), p1),
            None => map.to_axes(p1, a0),
        };
        let load = match trial {
            Ok(a1) => load(path, map, (s0, p0, a0), (s1, p1, a1), budget),
            Err(ReachError::AtCentre { .. }) => f64::INFINITY,
            Err(e) => return Err(e.into()),
        };
        match trial {
            Ok(a1) if load <= 1.0 => {
                h = piece * growth(load);
                let passed = Breakpoint { s: s1, axes: a1 };
                if in_hand.is_none() && s1 < s_end && load < STRETCH {
                    in_hand = Some((passed, p1));
                    continue;
                }
                let passed = settle(passed, p1, s0)?;
                out.push(passed);
                (s0, p0, a0, in_hand) = (s1, p1, passed.axes, None);
            }
            _ => {
                rest_failed |= s1 == s_end;
                h = piece * shrink(load);
                if let Some((kept, kept_point)) = in_hand.filter(|k| s0 + h <= k.0.s) {
                    // The longer trial failed short of where the kept piece ends: take that one.
                    h = kept.s - s0;
                    let kept = settle(kept, kept_point, s0)?;
                    out.push(kept);
                    (s0, p0, a0, in_hand) = (kept.s, kept_point, kept.axes, None);
                } else if piece * length < MIN_PIECE_MM {
                    return Err(CutError::NoConvergence { s: s0 });
                }
            }
        }
    }
    Ok(())
}

/// The next piece's length when `remaining` is left and `preferred` is allowed: the rest in one piece if
/// it fits, in two equal ones if two fit (no short last piece), else `preferred`.
fn last_two(remaining: f64, preferred: f64) -> f64 {
    if remaining <= preferred {
        remaining
    } else if remaining <= 2.0 * preferred {
        remaining / 2.0
    } else {
        preferred
    }
}

/// Fixed cut into `n` pieces of equal length.
pub fn cut_fixed(
    path: &Path,
    map: &AxisMap,
    (s_start, a_start): (f64, [f64; 2]),
    s_end: f64,
    n: usize,
    out: &mut Vec<Breakpoint>,
) -> Result<(), CutError> {
    let n = n.max(1);
    let mut near = a_start;
    for i in 1..=n {
        let s = if i == n {
            s_end
        } else {
            s_start + (s_end - s_start) * (i as f64 / n as f64)
        };
        let axes = map.to_axes(path.point(s), near)?;
        out.push(Breakpoint { s, axes });
        near = axes;
    }
    Ok(())
}

/// Largest turn of a rotary axis from `a0` to `a1`, as a multiple of [`MAX_ANGLE_STEP`].
fn turn_ratio(a0: [f64; 2], a1: [f64; 2], rotary: [bool; 2]) -> f64 {
    (0..2)
        .filter(|&i| rotary[i])
        .map(|i| (a1[i] - a0[i]).abs() / MAX_ANGLE_STEP)
        .fold(0.0, f64::max)
}

/// Next piece length factor after an accepted piece that used `load` of its budget (chord error ∝ h²).
fn growth(load: f64) -> f64 {
    if load <= 0.0 {
        4.0
    } else {
        (1.0 / load.sqrt()).clamp(0.5, 4.0)
    }
}

/// Piece length factor after a rejected trial: just short enough by the h² law, so that no piece is
/// shorter than it needs to be.
fn shrink(load: f64) -> f64 {
    if load.is_finite() {
        (1.0 / load.sqrt()).clamp(0.1, 0.999)
    } else {
        0.5
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use kinematics::PolarParams;
    use kinematics::StepperParams;
    use kinematics::polar::Polar;

    use super::*;
    use crate::options::Target;

    fn polar_map() -> AxisMap {
        let stepper = |name: &str| StepperParams {
            name: name.into(),
            step_distance: 0.01,
            position_min: None,
            position_max: None,
        };
        let params = PolarParams {
            bed: stepper("stepper_bed"),
            arm: stepper("stepper_arm"),
            z: stepper("stepper_z"),
            arm_zero_offset: 0.0,
            arm_lateral_offset: 0.0,
        };
        AxisMap::motors(
            Arc::new(Polar::new(params).expect("valid")),
            Target::Cylindrical,
        )
        .expect("map")
    }

    #[test]
    fn last_two_pieces_share_the_rest() {
        assert_eq!(last_two(1.0, 0.3), 0.3);
        assert_eq!(last_two(0.5, 0.3), 0.25);
        assert_eq!(last_two(0.2, 0.3), 0.2);
    }

    #[test]
    fn pieces_are_short_near_the_centre_and_long_far_from_it() {
        let map = polar_map();
        let target = 0.004;
        let mut lengths = Vec::new();
        for offset in [2.0, 100.0] {
            // A 40 mm line passing `offset` mm from the centre.
            let path = Path::Line {
                from: [-20.0, offset, 0.0],
                to: [20.0, offset, 0.0],
            };
            let start = map.to_axes(path.point(0.0), [0.0; 2]).expect("reachable");
            let mut cuts = Vec::new();
            let budget = Budget {
                bound: target,
                probe: target,
            };
            cut_adaptive(&path, &map, (0.0, start), 1.0, budget, &mut cuts).expect("cut");
            // Each piece, checked densely, stays within the target (with the probes' few percent).
            let dense: Vec<f64> = (1..64).map(|i| f64::from(i) / 64.0).collect();
            let mut from = (0.0, start);
            for cut in &cuts {
                let deviation =
                    chord_deviation(&path, &map, from, (cut.s, cut.axes), &dense).expect("finite");
                assert!(deviation <= target * 1.1, "offset {offset}: {deviation}");
                from = (cut.s, cut.axes);
            }
            let mut s_prev = 0.0;
            let shortest = cuts
                .iter()
                .map(|c| std::mem::replace(&mut s_prev, c.s))
                .zip(cuts.iter())
                .map(|(s0, c)| 40.0 * (c.s - s0))
                .fold(f64::INFINITY, f64::min);
            lengths.push(shortest);
        }
        // Chord error ∝ h²/ρ: at the closest approach, 50× farther allows ~√50 ≈ 7× longer pieces.
        assert!(lengths[1] > 4.0 * lengths[0], "{lengths:?}");
    }

    #[test]
    fn fixed_cut_has_equal_pieces() {
        let map = polar_map();
        let path = Path::Line {
            from: [10.0, 0.0, 0.0],
            to: [10.0, 10.0, 0.0],
        };
        let mut cuts = Vec::new();
        cut_fixed(&path, &map, (0.0, [10.0, 0.0]), 1.0, 4, &mut cuts).expect("cut");
        let s: Vec<f64> = cuts.iter().map(|c| c.s).collect();
        assert_eq!(s, [0.25, 0.5, 0.75, 1.0]);
        let last = cuts[3].axes;
        assert!(
            (last[0] - 200f64.sqrt()).abs() < 1e-12
                && (last[1] - std::f64::consts::FRAC_PI_4).abs() < 1e-12
        );
    }
}
