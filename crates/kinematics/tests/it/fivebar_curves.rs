//! The five-bar's singular curves as a map draws them, against the geometry written again in the tests
//! (`super::fivebar`'s circle–circle elbows): every drawn point is a singular pose (a side straight or folded, or the
//! distal links in line, where the inverse Jacobian's determinant vanishes), and every place where the distal links
//! pass through in line is drawn.

use kinematics::Kinematics;
use kinematics::fivebar::Fivebar;
use kinematics::workspace::{Bounds, SingularCurve, area_for};
use kinematics::{MachineParams, Turn};

use super::fivebar::{MODES, either_distal_turn, machine, turn};

const SPACING: f64 = 1.0;

fn bounds_of(fivebar: &Fivebar) -> Bounds {
    area_for(&MachineParams::Fivebar(fivebar.params().clone()))
        .expect("area")
        .0
}

fn curve<'a>(curves: &'a [SingularCurve], label: &str) -> &'a SingularCurve {
    curves
        .iter()
        .find(|c| c.label == label)
        .unwrap_or_else(|| panic!("no curve {label}: {curves:?}"))
}

/// |sin| of the angle between the distal links at `n`, from the independent elbows.
fn distal_sin(fivebar: &Fivebar, n: [f64; 2]) -> Option<f64> {
    let p = fivebar.params();
    let (_, [el, er]) = either_distal_turn(p, n)?;
    Some(turn(el, n, er).abs() / (p.left.distal * p.right.distal))
}

/// In all eight working modes, on the example's geometry: the points of the parallel curve have the distal links in
/// line to 1e-8 (|sin|) and our inverse Jacobian's determinant there is 1e-8 of its typical size; the serial curves lie
/// on their circles and the assembly exists at each of their points.
#[test]
fn every_drawn_point_is_a_singular_pose() {
    let (mut parallel_points, mut serial_points, mut worst_sin, mut worst_det) =
        (0, 0, 0.0f64, 0.0f64);
    for (left, right) in MODES {
        for distal in [Turn::Cw, Turn::Ccw] {
            let fivebar = machine(left, right, distal, 0.1);
            let curves = fivebar.singular_curves(&bounds_of(&fivebar), SPACING);
            for c in &curves {
                let points = c.pieces.iter().flatten();
                if c.label == "distal links in line" {
                    for &n in points {
                        let sin =
                            distal_sin(&fivebar, n).expect("both sides reach the parallel curve");
                        worst_sin = worst_sin.max(sin);
                        worst_det = worst_det.max(relative_det(&fivebar, n));
                        parallel_points += 1;
                    }
                } else {
                    serial_points += on_serial_circle(&fivebar, c.label, points.copied());
                }
            }
        }
    }
    eprintln!(
        "{parallel_points} parallel points (worst |sin| {worst_sin:.1e}, worst relative det {worst_det:.1e}), \
         {serial_points} serial points"
    );
    assert!(parallel_points > 1000 && serial_points > 1000);
    assert!(worst_sin < 1e-8, "{worst_sin}");
    assert!(worst_det < 1e-8, "{worst_det}");
}

/// |det| of our inverse Jacobian at `n` (from the side where the assembly exists) over the product of its rows'
/// lengths: 0 where the rows are parallel, the distal links in line.
fn relative_det(fivebar: &Fivebar, n: [f64; 2]) -> f64 {
    let mut rows = [[0.0; 3]; 3];
    // The crossing is located to 1e-9 mm; the configured assembly exists on one side of it.
    let found = [
        [0.0, 0.0],
        [1e-8, 0.0],
        [-1e-8, 0.0],
        [0.0, 1e-8],
        [0.0, -1e-8],
    ]
    .into_iter()
    .find(|d| {
        fivebar
            .jacobian([n[0] + d[0], n[1] + d[1], 0.0], &mut rows)
            .is_ok()
    });
    assert!(found.is_some(), "no pose beside {n:?}");
    let [a, b] = [rows[0], rows[1]];
    (a[0] * b[1] - a[1] * b[0]).abs() / (a[0].hypot(a[1]) * b[0].hypot(b[1]))
}

/// Checks a serial curve's points against its side's circle and the independent inverse; the number of points.
fn on_serial_circle(
    fivebar: &Fivebar,
    label: &str,
    points: impl Iterator<Item = [f64; 2]>,
) -> usize {
    let side = usize::from(label.starts_with("right"));
    let arm = fivebar.arm(side);
    let straight = label.ends_with("straight");
    let radius = if straight {
        arm.proximal + arm.distal
    } else {
        (arm.proximal - arm.distal).abs()
    };
    let mut count = 0;
    for n in points {
        let d = (n[0] - arm.base[0]).hypot(n[1] - arm.base[1]);
        assert!((d - radius).abs() < 1e-9, "{label}: {n:?} at {d}");
        // On the circle the side's elbow turns neither way: the pose is checked 1e-6 mm to the reachable side.
        let inward = if straight { -1e-6 } else { 1e-6 } / d;
        let beside = [
            n[0] + inward * (n[0] - arm.base[0]),
            n[1] + inward * (n[1] - arm.base[1]),
        ];
        let other = fivebar.arm(1 - side);
        let to_other = (n[0] - other.base[0]).hypot(n[1] - other.base[1]);
        let on_other = [
            other.proximal + other.distal,
            (other.proximal - other.distal).abs(),
        ]
        .iter()
        .any(|r| (to_other - r).abs() < 1e-6);
        // Where the other side is singular too, no nudge of this side's alone leaves both regular.
        if !on_other {
            assert!(
                either_distal_turn(fivebar.params(), beside).is_some(),
                "{label}: {n:?} has no pose"
            );
            count += 1;
        }
    }
    count
}

/// Short segments all over the area, in every working mode: wherever the distal links' turn changes sign between a
/// segment's ends (from the independent elbows, both sides reaching all along), a point of the drawn parallel curve
/// lies within the segment's length plus the drawing's spacing.
#[test]
fn every_crossing_of_the_distal_links_in_line_is_drawn() {
    let mut crossings = 0;
    for (left, right) in MODES {
        for distal in [Turn::Cw, Turn::Ccw] {
            let fivebar = machine(left, right, distal, 0.1);
            let b = bounds_of(&fivebar);
            let curves = fivebar.singular_curves(&b, SPACING);
            let drawn: Vec<[f64; 2]> = curves
                .iter()
                .filter(|c| c.label == "distal links in line")
                .flat_map(|c| c.pieces.iter().flatten().copied())
                .collect();
            let step = 3.7;
            let mut y = b.y_min + 0.3;
            while y < b.y_max {
                let mut x = b.x_min + 0.2;
                while x < b.x_max {
                    if let Some(mid) = sign_change(&fivebar, [x, y], [x + 0.8, y + 0.5]) {
                        crossings += 1;
                        let near = drawn
                            .iter()
                            .any(|d| (d[0] - mid[0]).hypot(d[1] - mid[1]) < 1.0 + SPACING);
                        assert!(
                            near,
                            "crossing near {mid:?} not drawn ({left:?}, {right:?}, {distal:?})"
                        );
                    }
                    x += step;
                }
                y += step;
            }
            let _ = curve(&curves, "distal links in line");
        }
    }
    eprintln!("{crossings} crossings checked");
    assert!(crossings > 100, "{crossings}");
}

/// The segment's midpoint if the distal links' turn (independent elbows) changes sign between its ends.
fn sign_change(fivebar: &Fivebar, a: [f64; 2], b: [f64; 2]) -> Option<[f64; 2]> {
    let p = fivebar.params();
    let signed = |n: [f64; 2]| {
        let (_, [el, er]) = either_distal_turn(p, n)?;
        Some(turn(el, n, er))
    };
    let (sa, sb) = (signed(a)?, signed(b)?);
    // Both sides reach the middle too: no side changes branch on the way.
    let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    signed(mid)?;
    (sa * sb < 0.0).then_some(mid)
}
