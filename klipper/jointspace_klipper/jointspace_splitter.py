# jointspace: the move transform that cuts a move where the machine asks for it
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# Like bed_mesh's MoveSplitter, a helper object of an extras module ([jointspace]): at klippy:connect it wraps the
# toolhead's move when the printer's kinematics is jointspace's and its moves need cutting. Where to cut is the
# library's answer (the machine's jointspace_move_waypoints); this file only queues the pieces.


class MoveSplitter:
    """The toolhead's move, wrapped. It checks each move whole before any part of it is queued (a refused move
    moves nothing), turns a polar bed in place on a circle of the centre's tolerance where a move passes through the
    centre or leaves it in a new direction, ends a move that ends within that circle on the centre itself, and (with
    cut_spans) cuts each move where jointspace's planner limits change (near the polar centre, SCARA and five-bar
    singular poses, step-rate limits), so check_move caps only the pieces that need it. G-code transforms (bed_mesh,
    skew_correction...) come first, as they end in the toolhead's move."""

    def __init__(self, config, kinematics_type):
        self.printer = config.get_printer()
        self.split_moves = config.getboolean("split_moves", True)
        self.kinematics_type = kinematics_type
        self.active = False
        self.cut_spans = 0
        self.printer.register_event_handler("klippy:connect", self._handle_connect)

    def _handle_connect(self):
        kin = self.printer.lookup_object("toolhead").get_kinematics()
        if not isinstance(kin, self.kinematics_type):
            return
        # centre_slowdown: klipper plans as Klipper's own polar does, whole moves only; a bed with a centre still
        # turns in place there (a move cannot turn it half a revolution at one instant).
        cut_spans = self.split_moves and kin.centre_slowdown == "exact"
        if cut_spans or kin.machine.has_centre:
            self._wrap(kin, cut_spans)

    def _wrap(self, kin, cut_spans):
        self.kin = kin
        self.machine = kin.machine
        self.cut_spans = 1 if cut_spans else 0
        self.toolhead = self.printer.lookup_object("toolhead")
        self.centre = self.machine.centre
        # Only a polar bed's whole turns need following.
        self.note_xy = kin.note_xy if self.machine.has_centre else (lambda pos: None)
        # Every toolhead move passes here, not only G-code's: probing, Z_TILT_ADJUST, bed_mesh's segments and other
        # extras move the toolhead directly, and a move leaving the polar centre must turn the bed in place whoever
        # asked for it. (Set at klippy:connect, before gcode_move binds the toolhead's move at klippy:ready.)
        self.toolhead_move = self.toolhead.move
        self.toolhead.move = self.move
        self.active = True

    def move(self, newpos, speed):
        if self.kin.joint_space:
            # Homing in joint space: X and Y stand for joint readings.
            self.toolhead_move(newpos, speed)
            return
        start = self.toolhead.get_position()
        if (newpos[0] == start[0] and newpos[1] == start[1]) or not (
                self.cut_spans or self._meets_centre(start, newpos)):
            # Nothing to cut: the move goes whole, and check_move refuses or caps it whole.
            self._queue(newpos, speed)
            return
        count, b = self.machine.waypoints(start, newpos, speed, self.toolhead.max_accel,
                                          self.kin.turn_angle or 0., self.cut_spans)
        if count == -2:
            self.kin.refuse_unreachable(start, newpos, self.machine.waypoint_error())
        if count < 1:
            # More pieces than worth it: the move stays whole and check_move caps it.
            self._queue(newpos, speed)
            return
        if count > 1:
            # Homed, Z in range: asked of the whole move before any piece is queued.
            self.kin.refuse_unreachable(start, newpos)
        for i in range(count):
            f = b[3 * i + 2]
            rest = newpos[2:] if i == count - 1 else [s + (e - s) * f for s, e in zip(start[2:], newpos[2:])]
            self._queue([b[3 * i], b[3 * i + 1]] + list(rest), speed)

    def _queue(self, pos, speed):
        self.toolhead_move(pos, speed)
        self.note_xy(pos)

    def _meets_centre(self, start, end):
        """Whether the move comes within twice the centre's tolerance (a superset of where the library routes it
        through the centre: Python's arithmetic need not round as the library's does), or starts within it."""
        if self.centre is None:
            return False
        cx, cy, radius = self.centre
        sx, sy = start[0] - cx, start[1] - cy
        dx, dy = end[0] - start[0], end[1] - start[1]
        t = min(1., max(0., -(sx * dx + sy * dy) / (dx * dx + dy * dy)))
        px, py = sx + t * dx, sy + t * dy
        return px * px + py * py < 4. * radius * radius
