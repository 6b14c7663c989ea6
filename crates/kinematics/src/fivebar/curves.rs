//! The five-bar's singular curves on the bed: each side stretched straight and folded (circles about its base joint
//! of radius `P + D` and `|P − D|`, kept where the configured assembly exists) and the distal links in line (the edge
//! of the region where the configured assembly exists at all: the distal links' turn changes sign across it).

use super::{Fivebar, LEFT, RIGHT};
use crate::ReachError;
use crate::curves::{SingularCurve, boundary_pieces, circle_pieces};
use crate::workspace::Bounds;

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
