//! The converter's output side: motion lines in the output's axes and units, positioning moves and moves without
//! planar motion, and
//! lines written through or as comments.

use std::io::Write;

use gcode::command::{Move, Span};
use kinematics::ReachError;

use super::Converter;
use super::checks::{check_feed, xyz};
use crate::error::ConvertError;
use crate::format::{feed_decimals, scale, to_units};
use crate::options::{Extrusion, FeedMode};
use kinematics::CENTRE_TURN_GAP;

impl<W: Write> Converter<W> {
    /// A move without XY motion (Z only, E only): one line, planar axes unchanged.
    pub(super) fn write_in_place(
        &mut self,
        start: [f64; 4],
        target: [f64; 4],
        feed: f64,
    ) -> Result<(), ConvertError> {
        let dz = target[2] - start[2];
        let de = target[3] - start[3];
        let distance = if dz != 0.0 { dz.abs() } else { de.abs() };
        if distance == 0.0 {
            return Ok(());
        }
        let e_units = to_units(target[3], self.options.decimals.extrusion);
        if self.write_motion(self.axes, target[2], e_units, distance / feed, feed)? {
            self.stats.segments += 1;
        }
        Ok(())
    }

    /// The first move after the start or a homing: a single `G0` to the target, no `F`.
    pub(super) fn positioning_move(
        &mut self,
        span: Span,
        target: [f64; 4],
    ) -> Result<(), ConvertError> {
        self.require_known(span, [true; 3])?;
        let p = xyz(target);
        // The start is unknown, but the target itself must be within the machine's limits.
        match self.map.machine().check_point(p) {
            Ok(()) | Err(ReachError::AtCentre { .. }) => {}
            Err(reason) => return Err(ConvertError::Unreachable { span, reason }),
        }
        let axes = match self.map.to_axes(p, self.axes) {
            Ok(a) => a,
            Err(ReachError::AtCentre { .. }) => {
                self.at_centre = true;
                self.map
                    .to_axes([p[0] + CENTRE_TURN_GAP, p[1], p[2]], self.axes)
                    .map_err(|reason| ConvertError::Unreachable { span, reason })?
            }
            Err(reason) => return Err(ConvertError::Unreachable { span, reason }),
        };
        self.position = Some(target);
        self.axes = axes;
        self.stats.positioning_moves += 1;
        let written_axes = self.axis_units(axes);
        let z = to_units(target[2], self.options.decimals.linear);
        let e = to_units(target[3], self.options.decimals.extrusion);
        self.buf.line_room(&mut self.out)?;
        self.buf.push_array(b"G0");
        self.push_axes(written_axes);
        self.buf.word('Z', z, self.options.decimals.linear);
        self.push_e(e);
        self.buf.push_array(b"\n");
        self.written.axes = written_axes;
        self.written.z = z;
        self.written.z_known = true;
        self.written.e = e;
        Ok(())
    }

    /// A move naming neither X nor Y while XY is unknown (`G1 Z5` after homing, a retraction): XY stays
    /// unknown (the interpreter's XY here is not where the machine is). A Z move is a positioning `G0 Z`;
    /// an extrude-only move is an ordinary timed `G1 E`.
    pub(super) fn write_z_and_e_only(&mut self, span: Span, m: &Move) -> Result<(), ConvertError> {
        let e = to_units(m.target[3], self.options.decimals.extrusion);
        let de = (e - self.written.e) as f64 / scale(self.options.decimals.extrusion);
        if m.named[2] {
            self.require_known(span, [false, false, true])?;
        }
        self.buf.line_room(&mut self.out)?;
        if m.named[2] {
            let z = to_units(m.target[2], self.options.decimals.linear);
            self.buf.push_array(b"G0");
            self.buf.word('Z', z, self.options.decimals.linear);
            self.push_e(e);
            self.written.z = z;
            self.written.z_known = true;
            self.stats.positioning_moves += 1;
        } else if de != 0.0 {
            check_feed(span, m.feed)?;
            self.buf.push_array(b"G1");
            self.push_e(e);
            let f = match self.options.feed {
                FeedMode::InverseTime => m.feed / de.abs() * 60.0,
                FeedMode::MotorSpace => m.feed * 60.0,
            };
            let f_decimals = feed_decimals(f);
            self.buf.push_array(b" F");
            self.buf.number(to_units(f, f_decimals), f_decimals);
            self.stats.segments += 1;
        } else {
            return Ok(());
        }
        self.buf.push_array(b"\n");
        self.written.e = e;
        Ok(())
    }

    /// Refuses to write a coordinate (of those `needed`) that neither the input nor the homing pose has set.
    pub(super) fn require_known(&self, span: Span, needed: [bool; 3]) -> Result<(), ConvertError> {
        match (0..3).find(|&i| needed[i] && !self.known[i]) {
            Some(i) => Err(ConvertError::UnknownPosition {
                span,
                axis: ['X', 'Y', 'Z'][i],
            }),
            None => Ok(()),
        }
    }

    pub(super) fn axis_units(&self, axes: [f64; 2]) -> [i64; 2] {
        [0, 1].map(|i| to_units(axes[i] * self.axis_scale[i], self.axis_decimals[i]))
    }

    pub(super) fn push_axes(&mut self, units: [i64; 2]) {
        let letters = self.options.letters();
        for i in 0..2 {
            self.buf.word(letters[i], units[i], self.axis_decimals[i]);
        }
    }

    /// E word for a point whose machine E is `e_units`, if the E position changes.
    pub(super) fn push_e(&mut self, e_units: i64) {
        let decimals = self.options.decimals.extrusion;
        if e_units == self.written.e {
            return;
        }
        match self.options.extrusion {
            Extrusion::Relative => self.buf.word('E', e_units - self.written.e, decimals),
            Extrusion::Absolute => self
                .buf
                .word('E', e_units - self.written.e_offset, decimals),
        }
    }

    /// Writes one `G1` to the given axes / Z / E that takes `time` seconds (its Cartesian time), or longer
    /// where a motor speed limit needs it: the written travel of every limited axis over its limit; `feed`
    /// (mm/s) is the E speed for extrude-only lines. The one place every motion line's `F` is computed,
    /// whatever the feed mode. Returns false when nothing changes after rounding (nothing written).
    pub(super) fn write_motion(
        &mut self,
        axes: [f64; 2],
        z: f64,
        e_units: i64,
        time: f64,
        feed: f64,
    ) -> Result<bool, ConvertError> {
        let units = self.axis_units(axes);
        let linear = self.options.decimals.linear;
        let z_units = to_units(z, linear);
        let moved =
            [0, 1].map(|i| (units[i] - self.written.axes[i]) as f64 / scale(self.axis_decimals[i]));
        let dz = if self.written.z_known {
            (z_units - self.written.z) as f64 / scale(linear)
        } else {
            0.0
        };
        let motor_length = (moved[0] * moved[0] + moved[1] * moved[1] + dz * dz).sqrt();
        let travel = [
            moved[0] / self.axis_scale[0],
            moved[1] / self.axis_scale[1],
            dz,
        ];
        let least = self.limits.min_time(travel);
        let time = if least > time {
            self.stats.limited += 1;
            least
        } else {
            time
        };
        let extrudes = e_units != self.written.e;
        if motor_length == 0.0 && !extrudes && self.written.z_known {
            return Ok(false);
        }
        self.buf.line_room(&mut self.out)?;
        self.buf.push_array(b"G1");
        if units != self.written.axes {
            self.push_axes(units);
        }
        if !self.written.z_known || z_units != self.written.z {
            self.buf.word('Z', z_units, linear);
        }
        self.push_e(e_units);
        let f = match self.options.feed {
            FeedMode::InverseTime => 60.0 / time.max(1e-9),
            FeedMode::MotorSpace if motor_length > 0.0 && time > 0.0 => motor_length / time * 60.0,
            FeedMode::MotorSpace => feed * 60.0,
        };
        let f_decimals = feed_decimals(f);
        self.buf.push_array(b" F");
        self.buf.number(to_units(f, f_decimals), f_decimals);
        self.buf.push_array(b"\n");
        self.written.axes = units;
        self.written.z = z_units;
        self.written.z_known = true;
        self.written.e = e_units;
        Ok(true)
    }

    pub(super) fn write_raw(&mut self, text: &str) -> Result<(), ConvertError> {
        self.buf.text(text.as_bytes(), &mut self.out)?;
        self.buf.text(b"\n", &mut self.out)?;
        Ok(())
    }

    pub(super) fn write_note(&mut self, raw: &str, why: &str) -> Result<(), ConvertError> {
        let code = raw.split(';').next().unwrap_or(raw).trim();
        self.write_raw(&format!("; {code} ({why})"))
    }
}
