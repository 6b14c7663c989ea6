//! The five-bar's special poses on the bed: where they lie, for drawing — each side stretched straight and folded
//! (circles about its base joint of radius `P + D` and `|P − D|`, kept where the configured assembly exists) and the
//! distal links in line (the edge of the region where the configured assembly exists at all: the distal links' turn
//! changes sign across it) — and how far a pose is from each, for `check`'s report.

use super::{Fivebar, LEFT, RIGHT};
use crate::curves::{boundary_pieces, circle_pieces};
use crate::workspace::{Bounds, SingularCurve};
use crate::{Clearance, ReachError, Vec3};

const STRAIGHT_OR_FOLDED: [&str; 2] = [
    "left arm straight or folded",
    "right arm straight or folded",
];
const STRAIGHT: [&str; 2] = ["left arm straight", "right arm straight"];
const FOLDED: [&str; 2] = ["left arm folded", "right arm folded"];
pub const DISTAL_IN_LINE: &str = "distal links in line";

pub(super) fn singular_curves(
    fivebar: &Fivebar,
    bounds: &Bounds,
    spacing: f64,
) -> Vec<SingularCurve> {
    let exists = |p: [f64; 2]| fivebar.pose(p[0], p[1]).is_ok();
    let mut curves = Vec::new();
    for side in [LEFT, RIGHT] {
        let arm = fivebar.arm(side);
        for (label, radius) in [
            (STRAIGHT[side], arm.proximal + arm.distal),
            (FOLDED[side], (arm.proximal - arm.distal).abs()),
        ] {
            let pieces = circle_pieces(arm.base, radius, bounds, spacing, exists);
            curves.push(SingularCurve { label, pieces });
        }
    }
    let assembly = |p: [f64; 2]| match fivebar.pose(p[0], p[1]) {
        Ok(_) => Some(true),
        Err(ReachError::BranchImpossible { .. }) => Some(false),
        Err(_) => None,
    };
    curves.push(SingularCurve {
        label: DISTAL_IN_LINE,
        pieces: boundary_pieces(bounds, spacing, assembly),
    });
    curves.retain(|c| !c.pieces.is_empty());
    curves
}

/// |sin| of each side's elbow angle and of the angle between the distal links at `p`, against the margin.
pub(super) fn clearances(fivebar: &Fivebar, p: Vec3, out: &mut Vec<Clearance>) {
    let Ok(pose) = fivebar.pose(p[0], p[1]) else {
        return;
    };
    let margin = fivebar.params().singularity_margin;
    for side in [LEFT, RIGHT] {
        out.push(Clearance {
            label: STRAIGHT_OR_FOLDED[side],
            value: pose.arm_sin[side],
            margin,
        });
    }
    out.push(Clearance {
        label: DISTAL_IN_LINE,
        value: pose.parallel_sin.abs(),
        margin,
    });
}
