//! Cutting a move into spans with their own caps.

use kinematics::{Kinematics, Vec3};

use super::limit::{MotorLimit, Span, caps};
use super::profile::{GENERAL_SPAN_MM, Line, Profile};
use super::rest::{RestEnd, rest_accel};

/// Spans of the move `start → end` requested at `speed` and `accel`, or an empty list when no limit binds
/// anywhere (the move then stays whole, exactly as Klipper plans it). An end the toolhead rests at
/// ([`Kinematics::rests_at`]) gets a span of its own, capped as the toolhead leaves or reaches it from rest
/// (`minimum_cruise_ratio`: the lookahead's, which says where it may cruise).
pub fn split(
    kin: &dyn Kinematics,
    limits: &[MotorLimit],
    start: Vec3,
    end: Vec3,
    speed: f64,
    accel: f64,
    minimum_cruise_ratio: f64,
) -> Vec<Span> {
    let Some(line) = Line::new(start, end).filter(|_| !limits.is_empty()) else {
        return Vec::new();
    };
    let length = line.length;
    // Fast path: bounds over the whole move; most moves are nowhere near a limit.
    let slack = limits.iter().all(|l| {
        let profile = Profile::new(kin, l.motor, &line);
        let (v, a) = caps(l, profile.bounds(kin, &line, 0.0, length), speed, accel);
        v >= speed && a >= accel
    });
    if slack {
        return Vec::new();
    }
    let profiles: Vec<(MotorLimit, Profile)> = limits
        .iter()
        .map(|l| (*l, Profile::new(kin, l.motor, &line)))
        .collect();
    let rests = [kin.rests_at(start), kin.rests_at(end)];
    let cuts = cuts(&line, &profiles, speed, rests);
    let mut raw: Vec<Span> = cuts
        .windows(2)
        .map(|pair| {
            let at_rest = (rests[0] && pair[0] == 0.0) || (rests[1] && pair[1] == length);
            span_caps(
                kin,
                &line,
                &profiles,
                (pair[0], pair[1]),
                (speed, accel),
                at_rest,
            )
        })
        .collect();
    if rests.contains(&true) {
        let sampled: Vec<MotorLimit> = profiles
            .iter()
            .filter(|(_, profile)| profile.is_sampled())
            .map(|(limit, _)| *limit)
            .collect();
        let rest = Rest {
            kin,
            sampled: &sampled,
            minimum_cruise_ratio,
        };
        rest.fit(&line, rests, &mut raw);
    }
    // Neighbours with equal caps are one span.
    raw.dedup_by(|next, kept| {
        let same = kept.max_speed == next.max_speed && kept.max_accel == next.max_accel;
        if same {
            kept.end = next.end;
        }
        same
    });
    let binds = raw
        .iter()
        .any(|s| s.max_speed < speed || s.max_accel < accel);
    if binds { raw } else { Vec::new() }
}

/// Cuts closer than this (mm) to each other or to an end of the move are one cut.
const CUT_TOLERANCE: f64 = 1e-9;

/// Where the spans of `line` begin and end (mm along it, sorted, from exactly 0 to exactly its length, so at least
/// one span even on a move shorter than [`CUT_TOLERANCE`]): where each motor's caps change, and a rest span's
/// length from each end the toolhead rests at.
fn cuts(line: &Line, profiles: &[(MotorLimit, Profile)], speed: f64, rests: [bool; 2]) -> Vec<f64> {
    let length = line.length;
    let rest_length = GENERAL_SPAN_MM.min(0.5 * length);
    let mut inner = Vec::new();
    for (limit, profile) in profiles {
        profile.breakpoints(line, limit, speed, &mut inner);
    }
    if rests[0] {
        inner.push(rest_length);
    }
    if rests[1] {
        inner.push(length - rest_length);
    }
    inner.retain(|&c| c >= CUT_TOLERANCE && c <= length - CUT_TOLERANCE);
    inner.sort_by(f64::total_cmp);
    let mut cuts = Vec::with_capacity(inner.len() + 2);
    cuts.push(0.0);
    let mut last = 0.0;
    for c in inner {
        if c - last >= CUT_TOLERANCE {
            cuts.push(c);
            last = c;
        }
    }
    cuts.push(length);
    cuts
}

/// The caps of the span `s0..s1` from every motor's bounds over it. Beside a rest pose the sampled motors are
/// left out: their caps come from [`Rest::fit`].
fn span_caps(
    kin: &dyn Kinematics,
    line: &Line,
    profiles: &[(MotorLimit, Profile)],
    (s0, s1): (f64, f64),
    (speed, accel): (f64, f64),
    at_rest: bool,
) -> Span {
    let mut span = Span {
        end: s1,
        max_speed: speed,
        max_accel: accel,
    };
    for (limit, profile) in profiles {
        if at_rest && profile.is_sampled() {
            continue;
        }
        let (v, a) = caps(limit, profile.bounds(kin, line, s0, s1), speed, accel);
        span.max_speed = span.max_speed.min(v);
        span.max_accel = span.max_accel.min(a);
    }
    span
}

/// What caps the spans beside rest poses: the limits of the motors without a closed form.
struct Rest<'a> {
    kin: &'a dyn Kinematics,
    sampled: &'a [MotorLimit],
    minimum_cruise_ratio: f64,
}

impl Rest<'_> {
    /// Cap the first span when the move leaves a rest pose and the last when it arrives at one.
    fn fit(&self, line: &Line, rests: [bool; 2], spans: &mut [Span]) {
        let n = spans.len();
        if n == 0 {
            return;
        }
        let first = spans[0].end;
        let last = line.length - if n > 1 { spans[n - 2].end } else { 0.0 };
        let end = line.at(line.length);
        let back = line.dir.map(|d| -d);
        let leave = rests[0].then(|| self.accel(line.start, line.dir, first, spans[0].max_accel));
        let arrive = rests[1].then(|| self.accel(end, back, last, spans[n - 1].max_accel));
        if let (Some(a), Some(b)) = (leave, arrive)
            && n <= 2
        {
            // The two rest spans are the whole move: one acceleration for both, meeting at their common cap.
            let accel = a.min(b);
            let length = first.max(last);
            for span in spans.iter_mut() {
                cap_from_rest(span, accel, length, f64::INFINITY);
            }
            return;
        }
        if let Some(accel) = leave {
            let next = spans.get(1).map_or(f64::INFINITY, |s| s.max_speed);
            cap_from_rest(&mut spans[0], accel, first, next);
        }
        if let Some(accel) = arrive {
            let previous = n
                .checked_sub(2)
                .map_or(f64::INFINITY, |i| spans[i].max_speed);
            cap_from_rest(&mut spans[n - 1], accel, last, previous);
        }
    }

    fn accel(&self, pose: Vec3, away: Vec3, length: f64, accel: f64) -> f64 {
        let end = RestEnd { pose, away, length };
        rest_accel(
            self.kin,
            self.sampled,
            end,
            accel,
            self.minimum_cruise_ratio,
        )
    }
}

/// A rest span of `length` accelerated at `accel` from rest: capped at the speed that reaches at its end, no
/// faster than the span beside it allows (so the toolhead does not cruise inside it faster than that), and its
/// acceleration no more than reaches that cap.
fn cap_from_rest(span: &mut Span, accel: f64, length: f64, neighbour_speed: f64) {
    let speed = (2.0 * accel * length)
        .sqrt()
        .min(span.max_speed)
        .min(neighbour_speed);
    span.max_speed = speed;
    span.max_accel = accel.min(speed * speed / (2.0 * length));
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::ScaraParams;
    use kinematics::polar::Polar;
    use kinematics::scara::Scara;
    use kinematics::{PolarParams, StepperParams};

    /// The FEKT arm (100 + 100 mm) with the example's singular band.
    fn arm() -> Scara {
        Scara::new(ScaraParams {
            singularity_margin: 0.05,
            ..ScaraParams::fekt_example()
        })
        .expect("valid params")
    }

    fn polar() -> Polar {
        let stepper = |name: &str, step: f64| StepperParams::new(name, step);
        Polar::new(PolarParams {
            bed: stepper("stepper_bed", std::f64::consts::TAU / 16000.0),
            arm: stepper("stepper_arm", 1.0 / 80.0),
            z: stepper("stepper_z", 0.0025),
            arm_zero_offset: 0.0,
            arm_lateral_offset: 0.0,
        })
        .expect("valid params")
    }

    fn joints() -> [MotorLimit; 2] {
        [0, 1].map(|motor| MotorLimit {
            motor,
            max_velocity: Some(6.0),
            max_accel: Some(300.0),
        })
    }

    /// A move shorter than the cut tolerance beside the straight arm (it rests there at both ends) used to lose its
    /// end cut to the tolerance, leaving no span at all, and the rest fit indexed the empty list. Now it is one span
    /// to its exact end, with a positive cap (the speed its acceleration from rest reaches over 1e-10 mm).
    #[test]
    fn a_move_shorter_than_the_cut_tolerance_is_one_span_to_its_end() {
        let kin = arm();
        for inside in [1e-12, 1e-10, 1e-9, 1e-6] {
            let start = [0.0, 200.0 - inside, 0.0];
            for dir in [
                [1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ] {
                let end = [0, 1, 2].map(|k| start[k] + 1e-10 * dir[k]);
                let length = Line::new(start, end).map_or(0.0, |l| l.length);
                let spans = split(&kin, &joints(), start, end, 100.0, 2000.0, 0.5);
                if let Some(last) = spans.last() {
                    assert_eq!(last.end, length, "{inside} {dir:?}: {spans:?}");
                }
                for s in &spans {
                    assert!(s.max_speed >= 0.0 && s.max_accel >= 0.0, "{s:?}");
                }
            }
        }
    }

    /// A cut within the tolerance of the move's end no longer replaces the end: the last span ends at the length.
    #[test]
    fn cuts_run_from_zero_to_the_exact_length() {
        let kin = arm();
        let line = Line::new([0.0, 150.0, 0.0], [0.0, 199.99, 0.0]).expect("a line");
        let profiles: Vec<(MotorLimit, Profile)> = joints()
            .iter()
            .map(|l| (*l, Profile::new(&kin, l.motor, &line)))
            .collect();
        let cuts = cuts(&line, &profiles, 100.0, [false, true]);
        assert_eq!(cuts.first(), Some(&0.0));
        assert_eq!(cuts.last(), Some(&line.length));
        assert!(
            cuts.windows(2).all(|w| w[1] - w[0] >= CUT_TOLERANCE),
            "{cuts:?}"
        );
        // Both rest cuts of a tiny move fall within the tolerance of its ends: one span.
        let tiny = Line::new([0.0, 199.99, 0.0], [0.0, 199.99 - 1e-10, 0.0]).expect("a line");
        assert_eq!(cuts_of(&kin, &tiny), vec![0.0, tiny.length]);
    }

    fn cuts_of(kin: &dyn Kinematics, line: &Line) -> Vec<f64> {
        let profiles: Vec<(MotorLimit, Profile)> = joints()
            .iter()
            .map(|l| (*l, Profile::new(kin, l.motor, line)))
            .collect();
        cuts(line, &profiles, 100.0, [true, true])
    }

    /// A move to a point Python reads as infinity, or with a Z so large its squared length overflows, has no line:
    /// its direction would be NaN (the polar bed's bounds clamped NaN and panicked; the SCARA's cuts were all
    /// dropped as non-finite, leaving no span). No spans: the segment check refuses such a move.
    #[test]
    fn a_move_without_a_finite_length_has_no_spans() {
        let bed = [MotorLimit {
            motor: 0,
            max_velocity: Some(5.0),
            max_accel: Some(200.0),
        }];
        for end in [
            [f64::INFINITY, 0.0, 1.0],
            [f64::INFINITY, 1.0, 1.0],
            [1e300, 1e300, 1.0],
        ] {
            assert!(split(&polar(), &bed, [0.0; 3], end, 100.0, 3000.0, 0.5).is_empty());
        }
        let spans = split(
            &arm(),
            &joints(),
            [0.0, 150.0, 1.0],
            [0.0, 199.99, 1e199],
            100.0,
            2000.0,
            0.5,
        );
        assert!(spans.is_empty(), "{spans:?}");
        assert!(Line::new([0.0; 3], [0.0, 0.0, 1e199]).is_none());
    }
}
