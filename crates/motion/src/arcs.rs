//! G2/G3 arcs split into straight chords of at most `resolution` mm, as Klipper's `[gcode_arcs]` does:
//! the same segment count and the same chord end points, so planned moves match Klipper's.

use gcode::Arc;
use std::f64::consts::TAU;

/// Most chords one arc may be split into (a kilometre of arc at the default 1 mm resolution): beyond that a
/// command is refused rather than allowed to exhaust memory and time.
pub const MAX_ARC_CHORDS: f64 = 1_000_000.0;

/// Points spread over the arc (not the chord ends), for checking the arc's reach before splitting it.
pub fn probe_points(arc: &Arc, count: usize) -> impl Iterator<Item = [f64; 3]> + '_ {
    let radius = arc.offset[0].hypot(arc.offset[1]);
    let start_angle = (-arc.offset[1]).atan2(-arc.offset[0]);
    let sweep = arc.sweep();
    (0..=count).map(move |i| {
        let f = i as f64 / count as f64;
        let a = start_angle + sweep * f;
        [
            arc.centre[0] + radius * a.cos(),
            arc.centre[1] + radius * a.sin(),
            arc.start[2] + (arc.target[2] - arc.start[2]) * f,
        ]
    })
}

/// How many chords [`split_arc`] makes of the arc.
pub fn chord_count(arc: &Arc, resolution: f64) -> f64 {
    let radius = arc.offset[0].hypot(arc.offset[1]);
    let flat_mm = radius * arc.sweep().abs();
    let linear = arc.target[2] - arc.start[2];
    let travel = if linear != 0.0 {
        flat_mm.hypot(linear)
    } else {
        flat_mm
    };
    (travel / resolution).floor().max(1.0)
}

/// The end points of the chords (the last one is the arc's target), X/Y/Z/E in machine coordinates.
///
/// Chord ends are computed in G-code coordinates and passed through G1's arithmetic (G92 offsets, M221
/// factor, absolute or relative E) exactly as Klipper's arc module feeds its own G1 commands, so the positions
/// agree to the last bit; E advances by equal steps of the written amount.
pub fn split_arc(arc: &Arc, resolution: f64) -> Vec<[f64; 4]> {
    let base = arc.base;
    let start = [
        arc.start[0] - base[0],
        arc.start[1] - base[1],
        arc.start[2] - base[2],
    ];
    let target = [
        arc.target[0] - base[0],
        arc.target[1] - base[1],
        arc.target[2] - base[2],
    ];
    // Radius vector from the centre to the start point.
    let r_p = -arc.offset[0];
    let r_q = -arc.offset[1];
    let centre_p = start[0] - r_p;
    let centre_q = start[1] - r_q;
    let rt_p = target[0] - centre_p;
    let rt_q = target[1] - centre_q;
    let mut angular_travel = (r_p * rt_q - r_q * rt_p).atan2(r_p * rt_p + r_q * rt_q);
    if angular_travel < 0.0 {
        angular_travel += TAU;
    }
    if arc.clockwise {
        angular_travel -= TAU;
    }
    if angular_travel == 0.0 && start[0] == target[0] && start[1] == target[1] {
        // Same start and end: a full circle.
        angular_travel = TAU;
    }
    let extra_turns = f64::from(arc.turns) * TAU;
    angular_travel += if arc.clockwise {
        -extra_turns
    } else {
        extra_turns
    };

    let linear_travel = target[2] - start[2];
    let radius = r_p.hypot(r_q);
    let flat_mm = radius * angular_travel;
    let mm_of_travel = if linear_travel != 0.0 {
        flat_mm.hypot(linear_travel)
    } else {
        flat_mm.abs()
    };
    let segments = (mm_of_travel / resolution).floor().max(1.0);
    let theta_per_segment = angular_travel / segments;
    let linear_per_segment = linear_travel / segments;

    let mut extruder = ArcExtrusion::new(arc, segments);
    // `segments` is at least 1 and bounded by the arc's length over the resolution.
    let count = segments as usize;
    let mut points = Vec::with_capacity(count);
    for i in 1..count {
        let i = i as f64;
        let (sin_t, cos_t) = (i * theta_per_segment).sin_cos();
        let p = -arc.offset[0] * cos_t + arc.offset[1] * sin_t;
        let q = -arc.offset[0] * sin_t - arc.offset[1] * cos_t;
        points.push([
            centre_p + p + base[0],
            centre_q + q + base[1],
            start[2] + i * linear_per_segment + base[2],
            extruder.next(),
        ]);
    }
    points.push([arc.target[0], arc.target[1], arc.target[2], extruder.next()]);
    points
}

/// E along an arc: the written amount split into equal G-code steps, each applied as a G1 `E` would be.
struct ArcExtrusion {
    machine_e: f64,
    gcode_e: f64,
    per_segment: f64,
    absolute: bool,
    factor: f64,
    base_e: f64,
}

impl ArcExtrusion {
    fn new(arc: &Arc, segments: f64) -> Self {
        let gcode_start = (arc.start[3] - arc.base[3]) / arc.extrude_factor;
        let gcode_e = if arc.absolute_extrude {
            gcode_start
        } else {
            0.0
        };
        let per_segment = arc
            .e_written
            .map_or(0.0, |written| (written - gcode_e) / segments);
        ArcExtrusion {
            machine_e: arc.start[3],
            gcode_e,
            per_segment,
            absolute: arc.absolute_extrude,
            factor: arc.extrude_factor,
            base_e: arc.base[3],
        }
    }

    fn next(&mut self) -> f64 {
        if self.per_segment != 0.0 {
            let written = self.gcode_e + self.per_segment;
            if self.absolute {
                self.gcode_e += self.per_segment;
                self.machine_e = written * self.factor + self.base_e;
            } else {
                self.machine_e += written * self.factor;
            }
        }
        self.machine_e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arc(start: [f64; 4], target: [f64; 4], offset: [f64; 2], clockwise: bool) -> Arc {
        Arc {
            start,
            target,
            centre: [start[0] + offset[0], start[1] + offset[1]],
            offset,
            clockwise,
            turns: 0,
            feed: 10.0,
            e_written: Some(target[3] - start[3]),
            base: [0.0; 4],
            extrude_factor: 1.0,
            absolute_extrude: false,
        }
    }

    #[test]
    fn half_circle_is_split_by_length_and_stays_on_the_circle() {
        // Radius 10 half circle: 31.4 mm of travel → 31 chords.
        let a = arc(
            [10.0, 0.0, 0.0, 0.0],
            [-10.0, 0.0, 0.0, 3.1],
            [-10.0, 0.0],
            false,
        );
        let pts = split_arc(&a, 1.0);
        assert_eq!(pts.len(), 31);
        for p in &pts {
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-12);
        }
        // Counter-clockwise from +X goes through +Y.
        assert!(pts[15][1] > 9.9);
        assert!((pts[30][3] - 3.1).abs() < 1e-12);
    }

    #[test]
    fn clockwise_goes_the_other_way_and_full_circle_when_start_is_end() {
        let a = arc(
            [10.0, 0.0, 0.0, 0.0],
            [-10.0, 0.0, 0.0, 0.0],
            [-10.0, 0.0],
            true,
        );
        assert!(split_arc(&a, 1.0)[15][1] < -9.9);
        let full = arc(
            [10.0, 0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0, 0.0],
            [-10.0, 0.0],
            false,
        );
        assert_eq!(split_arc(&full, 1.0).len(), 62);
    }
}
