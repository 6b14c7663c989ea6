# jointspace: Klipper's kinematics interface over the library's machine (jointspace_polar, jointspace_scara,
# jointspace_fivebar)
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# What Klipper's toolhead calls on a kinematics: the steppers, each with its motor's solver from the machine,
# positions, homing (SCARA and five-bar joints, the polar arm and a polar bed with an endstop home in joint space),
# the checks and speed caps of every move, and the status. The machine (jointspace_library.Machine) knows the
# geometry; these classes read no geometry key of their own.
import contextlib
import inspect
import math

KALICO = __name__.startswith("klippy.")
if KALICO:
    from klippy import chelper, stepper
else:
    import chelper
    import stepper


def _axis_letters(axes):
    # Klipper and Kalico pass "xyz" strings, the FEKT-SCARA fork lists of axis indexes.
    return set("xyz"[a] if isinstance(a, int) else str(a).lower() for a in axes)


def _coord(toolhead, values):
    try:
        return toolhead.Coord(tuple(values))
    except TypeError:  # Kalico: a namedtuple (x, y, z, e)
        return toolhead.Coord(*(list(values) + [0.0] * (4 - len(values))))


def _rail(section, units_in_radians=False):
    lookup = getattr(stepper, "LookupRail", None) or stepper.PrinterRail
    return lookup(section, units_in_radians=units_in_radians)


class JointspaceKinematics:
    """What Klipper's toolhead calls on a kinematics, shared by the polar, SCARA and five-bar machines. Subclasses
    create the steppers in Klipper's order and say how the XY joints home."""

    def __init__(self, toolhead, config, name, machine):
        self.printer = config.get_printer()
        self.toolhead = toolhead
        self.name = name
        self.machine = machine  # jointspace_library.Machine, built from this printer.cfg
        self.centre_slowdown = "exact"
        self.motor_steppers = []  # (machine motor, Klipper stepper) in Klipper's order, from the subclass
        self.wrapped = {}         # stepper -> the solver a wrapper (input shaper) wraps now, once swapped
        self.turn_angle = None    # the nozzle's unwrapped angle about a polar centre (note_xy)
        self.last_readings = {}
        self.joint_rails = {}     # section name -> rail of an XY joint that homes to an endstop
        self.homed = set()
        self.limit_z = (1.0, -1.0)
        self.joint_space = False  # True while homing moves in joint coordinates
        self.max_velocity, self.max_accel = toolhead.get_max_velocity()
        # As the library read them (Klipper's defaults and bounds), not read a second time.
        self.max_z_velocity = machine.value("max_z_velocity")
        self.max_z_accel = machine.value("max_z_accel")

    def _attach(self, toolhead, rails, xy_reach):
        # Every stepper gets its motor's solver from the machine (extra Z steppers share stepper_z's).
        self.motor_steppers = [(motor, s) for motor, rail in rails
                               for s in (rail.get_steppers() if hasattr(rail, "get_steppers")
                                         else [rail])]
        self.steppers = [s for _, s in self.motor_steppers]
        # Kalico's homing looks for the rails (with endstops) that move each axis.
        self.rails = [rail for _, rail in rails if hasattr(rail, "get_steppers")]
        self.own_solvers = {}
        for motor, s in self.motor_steppers:
            self.own_solvers[s] = self.machine.stepper_kinematics(motor)
            s.set_stepper_kinematics(self.own_solvers[s])
            s.set_trapq(toolhead.get_trapq())
            if KALICO:
                toolhead.register_step_generator(s.generate_steps)
        (x_min, y_min), (x_max, y_max) = xy_reach
        z_min, z_max = self.rail_z.get_range()
        self.axes_min = _coord(toolhead, (x_min, y_min, z_min))
        self.axes_max = _coord(toolhead, (x_max, y_max, z_max))
        sig = inspect.signature(toolhead.set_position).parameters.get("homing_axes")
        # The FEKT-SCARA fork takes axis indexes, Klipper and Kalico a string of letters.
        self.homing_axes_as_indexes = sig is not None and isinstance(sig.default, tuple)

    # -- positions --------------------------------------------------------------------------------
    def get_steppers(self):
        return list(self.steppers)

    def calc_position(self, stepper_positions):
        if self.joint_space:
            return self.joint_coordinates(stepper_positions)
        return self.machine.forward([stepper_positions[n] for n in self.machine.motor_names])

    def set_position(self, newpos, homing_axes):
        for s in self.steppers:
            s.set_position(newpos)
        # The motors' readings are declared anew (homing, SET_KINEMATIC_POSITION): whole turns start again.
        self.turn_angle = None
        self.note_xy(newpos)
        letters = _axis_letters(homing_axes)
        if "x" in letters and "y" in letters:
            self.homed.add("xy")
        if "z" in letters:
            self.limit_z = self.rail_z.get_range()

    def clear_homing_state(self, clear_axes):
        letters = _axis_letters(clear_axes)
        if "x" in letters or "y" in letters:
            self.homed.discard("xy")
        if "z" in letters:
            self.limit_z = (1.0, -1.0)

    def note_z_not_homed(self):
        self.clear_homing_state("z")

    # -- homing -----------------------------------------------------------------------------------
    def home(self, homing_state):
        axes = homing_state.get_axes()
        home_xy = 0 in axes or 1 in axes
        home_z = 2 in axes
        homing_state.set_axes(([0, 1] if home_xy else []) + ([2] if home_z else []))
        if home_xy:
            self.home_xy(homing_state)
        if home_z:
            self._home_rail(homing_state, 2, self.rail_z, [None, None, None])

    def _home_rail(self, homing_state, axis, rail, others):
        # Run to the endstop from the far end of the rail's travel (Klipper's rail homing).
        position_min, position_max = rail.get_range()
        info = rail.get_homing_info()
        homepos = list(others) + [None]
        homepos[axis] = info.position_endstop
        forcepos = list(homepos)
        if info.positive_dir:
            forcepos[axis] -= info.position_endstop - position_min
        else:
            forcepos[axis] += position_max - info.position_endstop
        homing_state.home_rails([rail], forcepos, homepos)

    @contextlib.contextmanager
    def joint_space_solvers(self):
        """While inside, the XY joints' solvers are linear ones (as FORCE_MOVE does): the toolhead's X and Y stand
        for the two joint readings (degrees for angles, mm for a rail), and a move turns the joints directly."""
        self.toolhead.flush_step_generation()
        saved = {}
        self.joint_space = True
        try:
            for motor, s in self.motor_steppers:
                if motor not in self.joint_names:
                    continue
                coeffs = [0., 0., 0.]
                coeffs[self.joint_names.index(motor)] = self.joint_scale(motor)
                sk = self.machine.linear_stepper_kinematics(*coeffs)
                wrapped = self._is_wrapped(s)
                saved[s] = (self._swap_solver(s, sk, wrapped), wrapped)
            yield
            self.toolhead.flush_step_generation()
        finally:
            for s, (sk, wrapped) in saved.items():
                self._swap_solver(s, sk, wrapped)
            self.joint_space = False

    def _swap_solver(self, s, sk, wrapped):
        """Makes sk the solver of stepper s and returns the one it replaces. Where something wraps our solver
        (`wrapped`: the input shaper allocates its own stepper_kinematics around it), the wrapped one is swapped and
        the wrapper stays, so homing moves are shaped as Klipper's own kinematics shape theirs."""
        if not wrapped:
            return s.set_stepper_kinematics(sk)
        wrapper = s.get_stepper_kinematics()
        host_lib = chelper.get_ffi()[1]
        # The new solver starts where the wrapper's motor stands (what set_stepper_kinematics keeps for a plain one).
        self.machine.set_commanded(sk, self.machine.commanded(wrapper))
        if host_lib.input_shaper_set_sk(wrapper, sk) < 0:
            raise self.printer.command_error("jointspace: the input shaper refused a homing solver")
        if hasattr(host_lib, "input_shaper_update_sk"):
            host_lib.input_shaper_update_sk(wrapper)
        inner, self.wrapped[s] = self.wrapped.get(s, self.own_solvers[s]), sk
        return inner

    def _is_wrapped(self, s):
        # Only Klipper's input shaper wraps a stepper's solver (and only hosts with input_shaper_set_sk do it so).
        return (s.get_stepper_kinematics() != self.own_solvers[s]
                and hasattr(chelper.get_ffi()[1], "input_shaper_set_sk"))

    def home_in_joint_space(self, homing_state, order, start):
        """Homes the XY joints one after the other in joint space, each homing move turning one joint alone.
        Returns the joint readings it ends at."""
        joints = list(start)
        with self.joint_space_solvers():
            for axis in order:
                rail = self.joint_rails[self.joint_names[axis]]
                others = list(joints) + [None]
                others[axis] = None
                self._home_rail(homing_state, axis, rail, others[:3])
                # Where the joint ended: its endstop, or short of it after Kalico's final retract.
                joints = self.toolhead.get_position()[:2]
        return joints

    def enter_joint_space(self):
        """Declares the toolhead at the motors' joint readings; call inside joint_space_solvers()."""
        readings = {name: s.get_commanded_position() for name, s in self.motor_steppers}
        pos = self.toolhead.get_position()
        pos[:3] = self.joint_coordinates(readings)
        self.toolhead.set_position(pos)

    def leave_joint_space(self):
        """Declares the toolhead at the pose the motors reached in joint space (after joint_space_solvers())."""
        readings = {name: s.get_commanded_position() for name, s in self.motor_steppers}
        pos = self.toolhead.get_position()
        pos[:3] = self.calc_position(readings)
        self.toolhead.set_position(pos)

    def joint_coordinates(self, stepper_positions):
        # The toolhead position while homing in joint space: X and Y are the joint readings.
        x, y = [stepper_positions[n] / self.joint_scale(n) for n in self.joint_names]
        return [x, y, stepper_positions["stepper_z"]]

    def set_homed_pose(self, homing_state, xyz):
        # The pose the joints were homed to, as a toolhead position; both XY axes are homed from now on.
        pos = self.toolhead.get_position()
        pos[0], pos[1] = xyz[0], xyz[1]
        self.toolhead.set_position(pos, homing_axes=self.homing_axes_arg("xy"))

    def homing_axes_arg(self, letters):
        if self.homing_axes_as_indexes:
            return ["xyz".index(c) for c in letters]
        return letters

    # -- moves ------------------------------------------------------------------------------------
    def refuse_unreachable(self, start, end, reason=None):
        """Raises the error of a G-code move that cannot be made (not homed, Z out of range, or `reason` from the
        library), naming its target, before any piece of it is queued (the move transform cuts moves into pieces,
        and a refused move must move nothing)."""
        target = "X%.3f Y%.3f Z%.3f" % tuple(end[:3])
        if reason is not None:
            raise self.out_of_range(end, reason)
        if "xy" not in self.homed:
            raise self.printer.command_error("Must home axis first: %s" % (target,))
        if end[2] != start[2] and not self.limit_z[0] <= end[2] <= self.limit_z[1]:
            if self.limit_z[0] > self.limit_z[1]:
                raise self.printer.command_error("Must home axis first: %s" % (target,))
            raise self.printer.command_error(
                "Move out of range: %s (Z beyond %.3f..%.3f)" % (target, self.limit_z[0], self.limit_z[1]))

    def out_of_range(self, end, reason):
        """The error of a move that cannot be made, naming its G-code target and why, the same whether the move
        transform or check_move finds it."""
        return self.printer.command_error(
            "Move out of range: X%.3f Y%.3f Z%.3f (%s)" % (end[0], end[1], end[2], reason))

    def check_move(self, move):
        if self.joint_space:
            return
        end = move.end_pos
        xy_moves = move.axes_d[0] or move.axes_d[1]
        if xy_moves and "xy" not in self.homed:
            raise move.move_error("Must home axis first")
        if move.axes_d[2]:
            if end[2] < self.limit_z[0] or end[2] > self.limit_z[1]:
                if self.limit_z[0] > self.limit_z[1]:
                    raise move.move_error("Must home axis first")
                raise move.move_error()
            # Klipper's Z limits, scaled by the Z share of the move.
            z_ratio = move.move_d / abs(move.axes_d[2])
            move.limit_speed(self.max_z_velocity * z_ratio, self.max_z_accel * z_ratio)
        exact = self.centre_slowdown == "exact"
        if xy_moves:
            speed = math.sqrt(move.max_cruise_v2) if exact else 0.
            try:
                limits, ends_at_rest = self.machine.check_move(move.start_pos, end, speed, move.accel)
            except ValueError as e:
                raise self.out_of_range(end, e)
            if limits is not None:
                move.limit_speed(limits[0], limits[1])
            if ends_at_rest:
                # A pose the arm may only rest at (nearly straight or folded): the move ends there at rest.
                move.limit_next_junction_speed(0.)
            if not exact:
                self.klipper_centre_slowdown(move)
        if exact and self.machine.caps_corners:
            self._limit_corner(move)

    def _limit_corner(self, move):
        """Klipper changes every motor's speed at once at a corner: cap the corner into this move so that the jump of
        each motor with an acceleration limit fits in it (as jointspace's own planner does)."""
        prev = self.toolhead.lookahead.get_last()
        if prev is None or not prev.is_kinematic_move:
            return
        speed = self.machine.junction_speed(prev.start_pos, prev.end_pos, prev.accel, move.end_pos, move.accel)
        if speed < float("inf"):
            prev.limit_next_junction_speed(speed)

    def klipper_centre_slowdown(self, move):
        pass

    # -- status -----------------------------------------------------------------------------------
    def note_xy(self, pos):
        """Follows the nozzle's angle about a polar centre through every position the move transform queues, its whole
        turns counted (the bed's reading keeps them; the toolhead position does not)."""
        if pos[0] == 0. and pos[1] == 0.:
            return
        angle = math.atan2(pos[1], pos[0])
        if self.turn_angle is not None:
            angle += 2. * math.pi * round((self.turn_angle - angle) / (2. * math.pi))
        self.turn_angle = angle

    def motor_readings(self):
        """The motors' commanded readings: where the queued moves leave them (a polar bed with its whole turns; on the
        centre the bed where it arrived), the last known ones where the position has no pose."""
        previous = dict(self.last_readings)
        if self.turn_angle is not None:
            for motor in self.turning_motors:
                previous[motor] = self.turn_angle
        motors = self.machine.inverse(self.toolhead.get_position(), previous)
        if motors is not None:
            self.last_readings = dict(zip(self.machine.motor_names, motors))
        return self.last_readings

    def get_status(self, eventtime):
        pos = self.toolhead.get_position()
        status = {
            "homed_axes": ("xy" if "xy" in self.homed else "")
            + ("z" if self.limit_z[0] <= self.limit_z[1] else ""),
            "axis_minimum": self.axes_min,
            "axis_maximum": self.axes_max,
        }
        # The motors' readings (angles in degrees, rails in mm): the bed's turns counted, defined at the centre too.
        readings = self.motor_readings()
        status["jointspace_joints"] = {
            n: (math.degrees(v) if n in self.angle_motors else v) for n, v in readings.items()}
        margin = self.machine.reach_margin(pos)
        if margin is not None:
            status["jointspace_reach_margin"] = margin
        status["jointspace_kinematics"] = self.name
        status["jointspace_offsets"] = self.offsets
        return status


class PolarKinematics(JointspaceKinematics):
    """Rotating bed (stepper_bed), radial arm (stepper_arm), Z; with the arm's zero and sideways offsets."""

    joint_names = ("stepper_arm", "stepper_bed")
    angle_motors = ("stepper_bed",)
    turning_motors = ("stepper_bed",)

    def __init__(self, toolhead, config, machine):
        JointspaceKinematics.__init__(self, toolhead, config, "jointspace_polar", machine)
        # Created in Klipper's order (bed, arm, z), so the MCU objects get the same ids. A bed with an endstop
        # is a rail that homes (in degrees) after the arm; without one it is declared at angle 0.
        bed_section = config.getsection("stepper_bed")
        if bed_section.get("endstop_pin", None, note_valid=False) is not None:
            stepper_bed = stepper.LookupMultiRail(bed_section, units_in_radians=True)
            self.joint_rails["stepper_bed"] = stepper_bed
        else:
            stepper_bed = stepper.PrinterStepper(bed_section, units_in_radians=True)
        rail_arm = _rail(config.getsection("stepper_arm"))
        self.rail_z = stepper.LookupMultiRail(config.getsection("stepper_z"))
        self.joint_rails["stepper_arm"] = rail_arm
        max_xy = rail_arm.get_range()[1]
        self._attach(toolhead, [("stepper_bed", stepper_bed), ("stepper_arm", rail_arm),
                                ("stepper_z", self.rail_z)],
                     ((-max_xy, -max_xy), (max_xy, max_xy)))
        self.v_rad_max = config.getfloat("max_angular_velocity", 0., minval=0.)
        self.centre_slowdown = config.getchoice("centre_slowdown",
                                                {"exact": "exact", "klipper": "klipper"},
                                                "exact")
        self.offsets = {k: machine.value(k) for k in ("arm_zero_offset", "arm_lateral_offset")}

    def joint_scale(self, name):
        # Motor units per toolhead unit while homing: the arm in mm, the bed's reading in degrees.
        return math.pi / 180. if name == "stepper_bed" else 1.

    def home_xy(self, homing_state):
        # The arm runs to its endstop, then the bed to its own if it has one; otherwise the bed is declared at
        # angle 0 (as Klipper's polar does).
        order = [0, 1] if "stepper_bed" in self.joint_rails else [0]
        joints = self.home_in_joint_space(homing_state, order, [0., 0.])
        bed = math.radians(joints[1])
        self.set_homed_pose(homing_state, self.machine.forward([bed, joints[0], 0.]))

    def klipper_centre_slowdown(self, move):
        # Klipper's own rule (polar.py): slow the whole move by the bed speed at its closest approach,
        # scaled from max_velocity. Kept for printers that want Klipper's planning exactly.
        if not self.v_rad_max:
            return
        d = _distance_to_centre(move.start_pos, move.end_pos)
        if d == 0:
            return
        v_angular = math.sqrt(move.max_cruise_v2) / d
        if self.v_rad_max < v_angular:
            scale = self.v_rad_max / v_angular
            move.limit_speed(self.max_velocity * scale, self.max_accel * scale)


def _distance_to_centre(p1, p2):
    # Distance of the segment p1-p2 from X0 Y0, in Klipper's arithmetic (so centre_slowdown: klipper plans
    # bit for bit as Klipper's polar does).
    ab_x = p2[0] - p1[0]
    ab_y = p2[1] - p1[1]
    ap_x = -p1[0]
    ap_y = -p1[1]
    dot = ab_x * ap_x + ab_y * ap_y
    length = math.sqrt(ab_x ** 2 + ab_y ** 2)
    if dot <= 0:
        return math.sqrt(ap_x ** 2 + ap_y ** 2)
    if dot >= length ** 2:
        return math.sqrt(p2[0] ** 2 + p2[1] ** 2)
    return abs(ab_x * ap_y - ab_y * ap_x) / length


class JointArmKinematics(JointspaceKinematics):
    """Arms whose two XY motors turn joints (SCARA, five-bar): each joint with an endstop homes to it in joint space,
    one after the other, and the nozzle is where forward kinematics puts their readings; or [printer] home_position
    declares the pose at G28 (FEKT-SCARA's homing). Subclasses name the joints, the keys of their offsets and their
    XY bounds."""

    turning_motors = ()

    def __init__(self, toolhead, config, name, machine):
        JointspaceKinematics.__init__(self, toolhead, config, name, machine)
        self.home_position = self.machine.declared_home()
        joints = []
        for joint in self.joint_names:
            section = config.getsection(joint)
            if section.get("endstop_pin", None, note_valid=False) is not None:
                joints.append(stepper.LookupMultiRail(section, units_in_radians=True))
                self.joint_rails[joint] = joints[-1]
            elif self.home_position is not None:
                # A declared pose: a joint needs no endstop.
                joints.append(stepper.PrinterStepper(section, units_in_radians=True))
            else:
                raise config.error(
                    "%s: [%s] needs endstop_pin (the joints home to endstops) "
                    "or [printer] needs home_position (the pose homing declares)" % (name, joint))
        self.rail_z = stepper.LookupMultiRail(config.getsection("stepper_z"))
        self.offsets = {k: machine.value(k) for k in self.offset_keys}
        self._attach(toolhead, list(zip(self.joint_names, joints)) + [("stepper_z", self.rail_z)],
                     self.xy_bounds())

    @property
    def angle_motors(self):
        return self.joint_names

    def joint_scale(self, name):
        # While homing, the toolhead's X and Y are the joint readings in degrees (as position_endstop).
        return math.pi / 180. if name in self.joint_names else 1.

    def home_xy(self, homing_state):
        if self.home_position is not None:
            # FEKT-SCARA's homing: no motion, the arm is declared at home_position.
            pos = self.toolhead.get_position()
            pos[0], pos[1] = self.home_position[0], self.home_position[1]
            self.toolhead.set_position(pos, homing_axes=self.homing_axes_arg("xy"))
            return
        joints = self.home_in_joint_space(homing_state, [0, 1], [0., 0.])
        motors = [math.radians(joints[0]), math.radians(joints[1]), 0.]
        self.set_homed_pose(homing_state, self.machine.forward(motors))


class ScaraKinematics(JointArmKinematics):
    """SCARA: shoulder motor (stepper_a), elbow motor (stepper_b, coupled to the shoulder), Z."""

    joint_names = ("stepper_a", "stepper_b")
    offset_keys = ("offset_x", "offset_y")

    def __init__(self, toolhead, config, machine):
        JointArmKinematics.__init__(self, toolhead, config, "jointspace_scara", machine)

    def xy_bounds(self):
        # The square about the shoulder that holds the arm's reach.
        reach = self.machine.value("link1_length") + self.machine.value("link2_length")
        ox, oy = self.offsets["offset_x"], self.offsets["offset_y"]
        return (ox - reach, oy - reach), (ox + reach, oy + reach)


class FivebarKinematics(JointArmKinematics):
    """Five-bar (parallel) SCARA: the left and right base joints (stepper_left, stepper_right), each turning a
    proximal link, the distal links joined at the nozzle; Z."""

    joint_names = ("stepper_left", "stepper_right")
    offset_keys = ("left_base_x", "left_base_y", "right_base_x", "right_base_y")

    def __init__(self, toolhead, config, machine):
        JointArmKinematics.__init__(self, toolhead, config, "jointspace_fivebar", machine)

    def xy_bounds(self):
        # The nozzle is within each side's reach of its base joint: the overlap of the squares about both bases.
        lows, highs = [], []
        for side in ("left", "right"):
            reach = (self.machine.value(side + "_proximal_length")
                     + self.machine.value(side + "_distal_length"))
            base = (self.offsets[side + "_base_x"], self.offsets[side + "_base_y"])
            lows.append([c - reach for c in base])
            highs.append([c + reach for c in base])
        return ((max(lows[0][0], lows[1][0]), max(lows[0][1], lows[1][1])),
                (min(highs[0][0], highs[1][0]), min(highs[0][1], highs[1][1])))
