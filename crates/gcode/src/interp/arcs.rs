//! Arc geometry: the centre of an R arc, the radius check of an I J arc, and what a checked arc
//! line gives.

use crate::command::Position;
use crate::error::ErrorKind;

/// Start and end radii of an arc may differ by this much (mm) … (also how far an R arc's half chord
/// may exceed R: slicers round R and the end point to 3 decimals)
const ARC_RADIUS_TOLERANCE_MM: f64 = 0.005;
/// … or by this fraction of the radius, whichever is larger.
const ARC_RADIUS_TOLERANCE_REL: f64 = 1e-3;

/// Most extra turns an arc's `P` may ask for. Real prints use a handful; the bound keeps a stray
/// `P4000000000` from becoming trillions of chords downstream.
pub const MAX_ARC_TURNS: u32 = 1000;

/// Centre offset (from the start) of an R arc: short arc for R > 0, long arc for R < 0.
pub(super) fn centre_offset_from_radius(
    start: &Position,
    target: &Position,
    radius: f64,
    clockwise: bool,
) -> Result<[f64; 2], ErrorKind> {
    let (dx, dy) = (target[0] - start[0], target[1] - start[1]);
    let chord = dx.hypot(dy);
    let half = chord / 2.0;
    let r = radius.abs();
    if r == 0.0 {
        return Err(ErrorKind::ArcZeroRadius);
    }
    if chord == 0.0 {
        return Err(ErrorKind::ArcRClosed);
    }
    if half > r + ARC_RADIUS_TOLERANCE_MM {
        return Err(ErrorKind::ArcRadiusTooSmall);
    }
    // Distance from the chord's midpoint to the centre (0 when the chord is a diameter).
    let h = (r * r - half * half).max(0.0).sqrt();
    // Counter-clockwise short arcs have their centre left of the chord; each flip changes side.
    let left = if clockwise == (radius < 0.0) {
        1.0
    } else {
        -1.0
    };
    let (ux, uy) = (dx / chord, dy / chord);
    Ok([dx / 2.0 - left * h * uy, dy / 2.0 + left * h * ux])
}

/// What an arc line gives besides the interpreter's state, once checked.
pub(super) struct ArcEnds {
    pub(super) target: Position,
    pub(super) centre: [f64; 2],
    pub(super) offset: [f64; 2],
    pub(super) clockwise: bool,
    pub(super) turns: u32,
    pub(super) speed: f64,
    pub(super) e_written: Option<f64>,
}

/// The XY centre at `offset` from `start`, when finite and as far from `target` as from `start`,
/// and the radius at the start (`Arc::radius`, to the bit: the statistics reuse it).
/// (Inline, as [`check_radii`]: the fast path's arcs inlined both when they were beside them.)
#[inline]
pub(super) fn checked_centre(
    start: &Position,
    target: &Position,
    offset: [f64; 2],
) -> Result<([f64; 2], f64), ErrorKind> {
    let centre = [start[0] + offset[0], start[1] + offset[1]];
    if !(centre[0].is_finite() && centre[1].is_finite()) {
        return Err(ErrorKind::NumberOverflow);
    }
    let radius = check_radii(start, target, &centre)?;
    Ok((centre, radius))
}

/// Radius at start and end must agree (within 0.005 mm or 0.1 %); gives the start radius.
#[inline]
fn check_radii(start: &Position, target: &Position, centre: &[f64; 2]) -> Result<f64, ErrorKind> {
    let start_radius = (start[0] - centre[0]).hypot(start[1] - centre[1]);
    let end_radius = (target[0] - centre[0]).hypot(target[1] - centre[1]);
    let diff = (start_radius - end_radius).abs();
    let relative = diff / start_radius.max(end_radius);
    if diff > ARC_RADIUS_TOLERANCE_MM && relative > ARC_RADIUS_TOLERANCE_REL {
        return Err(ErrorKind::ArcInconsistent {
            start_radius,
            end_radius,
        });
    }
    Ok(start_radius)
}
