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

/// Where the spans of `line` begin and end (mm along it, sorted, from 0 to its length): where each motor's caps
/// change, and a rest span's length from each end the toolhead rests at.
fn cuts(line: &Line, profiles: &[(MotorLimit, Profile)], speed: f64, rests: [bool; 2]) -> Vec<f64> {
    let length = line.length;
    let rest_length = GENERAL_SPAN_MM.min(0.5 * length);
    let mut cuts = vec![0.0, length];
    for (limit, profile) in profiles {
        profile.breakpoints(line, limit, speed, &mut cuts);
    }
    if rests[0] {
        cuts.push(rest_length);
    }
    if rests[1] {
        cuts.push(length - rest_length);
    }
    cuts.retain(|c| c.is_finite());
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
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
