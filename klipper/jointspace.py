# jointspace kinematics for Klipper and Kalico: SCARA arms and polar printers
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# Loaded from a [jointspace] config section (klippy/extras/ on Klipper, klippy/plugins/ on Kalico), it
# registers the kinematics "jointspace_polar" and "jointspace_scara" before [printer] imports them. The
# machine itself (geometry, offsets, limits, reach) lives in libjointspace_klipper.so, built from the same
# printer.cfg keys the jointspace command line reads; Klipper's itersolve calls that library for every step.
import contextlib
import importlib.util
import inspect
import logging
import math
import os
import sys
import types

KALICO = __name__.startswith("klippy.")
if KALICO:
    from klippy import chelper, stepper
else:
    import chelper
    import stepper

HERE = os.path.dirname(os.path.realpath(__file__))


def _load_sibling(name):
    # By path: the hosts load this file under different package names (Kalico's plugins as klippy.extras.*),
    # so a relative import would look in the wrong package.
    spec = importlib.util.spec_from_file_location(name, os.path.join(HERE, name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


jointspace_scan = _load_sibling("jointspace_scan")

LIBRARY_NAME = "libjointspace_klipper.so"
ERROR_LEN = 512


######################################################################
# The library
######################################################################

def _cdef_text():
    # The C interface, from jointspace.h (preprocessor lines dropped: cffi reads declarations only).
    with open(os.path.join(HERE, "jointspace.h")) as f:
        return "".join(l for l in f if not l.lstrip().startswith("#"))


def _library_path(config):
    # A path the owner gave must exist: silently loading another library would hide a mistake.
    given = [("[jointspace] library", config.get("library", None)
              if config.get_name() == "jointspace" else None),
             ("the environment variable JOINTSPACE_LIBRARY", os.environ.get("JOINTSPACE_LIBRARY"))]
    for where, path in given:
        if path:
            if not os.path.isfile(path):
                raise config.error(
                    "jointspace: %s names %s, which does not exist (build it with klipper/install.sh, "
                    "or remove the setting to use the library this plug-in was installed with)" % (where, path))
            return os.path.realpath(path)
    for path in (os.path.join(HERE, LIBRARY_NAME), os.path.join(HERE, "..", "target", "release", LIBRARY_NAME)):
        if os.path.isfile(path):
            return os.path.realpath(path)
    raise config.error(
        "jointspace: %s not found (run klipper/install.sh, or set "
        "[jointspace] library: /path/to/%s)" % (LIBRARY_NAME, LIBRARY_NAME))


def _header_hash():
    # FNV-1a of jointspace.h, as the library computes it of the header it was built from.
    with open(os.path.join(HERE, "jointspace.h"), "rb") as f:
        data = f.read()
    value = 0xcbf29ce484222325
    for byte in bytearray(data):
        value = ((value ^ byte) * 0x100000001b3) & 0xffffffffffffffff
    return value


def _check_built_from_this_header(config, lib, path):
    try:
        theirs = lib.jointspace_header_hash()
    except AttributeError:
        theirs = None
    if theirs != _header_hash():
        raise config.error(
            "jointspace: %s was built from another version of jointspace.h than this plug-in's: rebuild it "
            "(klipper/install.sh, or cargo build --release -p klipper) and restart" % (path,))


def _stepper_kinematics_layout(ffi):
    # Klipper's struct stepper_kinematics (itersolve.h, the same in the three hosts; the tests compile against
    # each host's header) as laid out on this platform: catches a library built for another ABI.
    # It also gives the probe of the host's arithmetic the offset of calc_position_cb.
    ffi.cdef("""
        struct jointspace_layout_probe {
            double step_dist, commanded_pos; void *sc;
            double last_flush_time, last_move_time; void *tq; int active_flags;
            double gen_steps_pre_active, gen_steps_post_active;
            void *calc_position_cb; void *post_cb;
        };""")
    t = "struct jointspace_layout_probe"
    return [ffi.sizeof(t), ffi.offsetof(t, "commanded_pos"),
            ffi.offsetof(t, "active_flags"), ffi.offsetof(t, "calc_position_cb"),
            ffi.offsetof(t, "post_cb")]


_LIBRARY = {}
PROBE_MOVE = """
    struct jointspace_probe_move {
        double print_time, move_t, start_v, half_accel;
        double start_pos[3], axes_r[3];
        void *node[2];
    };"""


def _host_arithmetic(ffi, lib):
    """Whether the host's C helper rounds like fused multiply-adds (Kalico compiles it with -march=native):
    the host's own polar arm solver and ours, in both arithmetics, on sample moves. Our solvers then compute
    positions exactly as the host's would, so step times agree to the bit. None when neither matches."""
    host_lib = chelper.get_ffi()[1]
    sk = ffi.gc(host_lib.polar_stepper_alloc(b"r"), host_lib.free)
    probe = ffi.cast("struct jointspace_layout_probe *", sk)
    calc = ffi.cast("double (*)(void *, void *, double)", probe.calc_position_cb)
    move = ffi.new("struct jointspace_probe_move *")
    state = 12345
    matches = {0: True, 1: True}
    for _ in range(400):
        values = []
        for _ in range(9):
            state = (state * 6364136223846793005 + 1442695040888963407) % (1 << 64)
            values.append((state >> 11) / float(1 << 53))
        move.move_t = 1. + values[0]
        move.start_v = 300. * values[1]
        move.half_accel = 1500. * (values[2] - .5)
        move.start_pos[0], move.start_pos[1] = 600. * (values[3] - .5), 600. * (values[4] - .5)
        move.axes_r[0] = values[5] - .5
        move.axes_r[1] = math.sqrt(max(0., 1. - move.axes_r[0] ** 2)) * (1 if values[6] > .5 else -1)
        t = values[7] * move.move_t
        host = calc(sk, move, t)
        for fused in (0, 1):
            if lib.jointspace_polar_radius(move, t, fused) != host:
                matches[fused] = False
    if matches[0]:
        return 0
    if matches[1]:
        return 1
    return None


def load_library(config):
    """(ffi, lib): the library loaded into Klipper's own cffi instance, so its stepper_kinematics pointers
    are the ones Klipper's stepper code accepts."""
    ffi, _ = chelper.get_ffi()
    if "lib" not in _LIBRARY:
        path = _library_path(config)
        ffi.cdef(_cdef_text())
        lib = ffi.dlopen(path)
        _check_built_from_this_header(config, lib, path)
        ours = ffi.new("size_t[5]")
        lib.jointspace_stepper_kinematics_layout(ours)
        theirs = _stepper_kinematics_layout(ffi)
        if list(ours) != theirs:
            raise config.error(
                "jointspace: %s was built for another struct stepper_kinematics "
                "(layout %s, host %s)" % (path, list(ours), theirs))
        ffi.cdef(PROBE_MOVE)
        fused = _host_arithmetic(ffi, lib)
        if fused is None:
            logging.warning("jointspace: the host's step solver rounds in neither known way; "
                            "step times may differ from its own kinematics by a tick")
            fused = 0
        logging.info("jointspace: loaded %s (%s), %s arithmetic", path,
                     ffi.string(lib.jointspace_version()).decode(),
                     "fused multiply-add" if fused else "plain")
        _LIBRARY["lib"] = lib
        _LIBRARY["fused"] = fused
    return ffi, _LIBRARY["lib"]


def _config_text(config):
    # The sections the machine is built from, as printer.cfg text (Klipper has already resolved includes
    # and the SAVE_CONFIG block). Reading them here marks nothing as used.
    names = ["printer"] + [s.get_name() for s in config.get_prefix_sections("stepper_")]
    lines = []
    for name in names:
        section = config.getsection(name)
        lines.append("[%s]" % (name,))
        for option in section.get_prefix_options(""):
            value = section.get(option, note_valid=False)
            lines.append("%s: %s" % (option, str(value).replace("\n", "\n  ")))
    return "\n".join(lines) + "\n"


class Machine:
    """The library's machine for this printer.cfg, and the questions asked of it."""

    def __init__(self, config):
        self.ffi, self.lib = load_library(config)
        ffi, lib = self.ffi, self.lib
        error = ffi.new("char[]", ERROR_LEN)
        # Built from the owner's printer.cfg as the jointspace command line builds it (errors name its lines); from
        # the sections as Klipper read them when there is no such file.
        config_file = config.get_printer().get_start_args().get("config_file")
        if config_file and os.path.isfile(config_file):
            handle = lib.jointspace_machine_new_from_file(
                os.path.abspath(config_file).encode(), _LIBRARY["fused"], error, ERROR_LEN)
        else:
            handle = lib.jointspace_machine_new(_config_text(config).encode(), _LIBRARY["fused"],
                                                error, ERROR_LEN)
        if handle == ffi.NULL:
            raise config.error("jointspace: %s" % (ffi.string(error).decode(),))
        self.handle = ffi.gc(handle, lib.jointspace_machine_free)
        # Keys the library read are ours: tell Klipper they are used (it refuses unknown keys).
        for line in ffi.string(lib.jointspace_machine_read_keys(self.handle)).decode().splitlines():
            section, key = line.split(" ", 1)
            config.getsection(section).get(key, None)
        count = lib.jointspace_motor_count(self.handle)
        self.motor_names = [ffi.string(lib.jointspace_motor_name(self.handle, i)).decode()
                            for i in range(count)]
        self._motors = ffi.new("double[]", count)
        self._xyz = ffi.new("double[3]")
        self._limits = ffi.new("double[2]")
        self._corner = ffi.new("double[9]")
        # Asked once: most machines have no acceleration-limited motor, and then no corner needs capping.
        self.caps_corners = bool(lib.jointspace_caps_corners(self.handle))
        self._error = error
        self._margin = ffi.new("double *")
        # A polar bed's centre (x, y, the tolerance within which a path meets it), or None.
        centre = ffi.new("double[3]")
        self.centre = (list(centre) if lib.jointspace_rotation_centre(self.handle, centre) == 0
                       else None)
        self.has_centre = self.centre is not None

    def stepper_kinematics(self, name):
        ffi, lib = self.ffi, self.lib
        sk = lib.jointspace_stepper_alloc(self.handle, name.encode())
        if sk == ffi.NULL:
            raise self.error("no solver for %s" % (name,))
        return ffi.gc(sk, chelper.get_ffi()[1].free)

    def commanded(self, sk):
        return self.ffi.cast("struct jointspace_layout_probe *", sk).commanded_pos

    def set_commanded(self, sk, value):
        self.ffi.cast("struct jointspace_layout_probe *", sk).commanded_pos = value

    def linear_stepper_kinematics(self, cx, cy, cz):
        sk = self.lib.jointspace_linear_stepper_alloc(cx, cy, cz, _LIBRARY["fused"])
        return self.ffi.gc(sk, chelper.get_ffi()[1].free)

    def error(self, message):
        return Exception("jointspace: %s" % (message,))

    def _reason(self):
        return self.ffi.string(self._error).decode()

    def forward(self, motors):
        for i, value in enumerate(motors):
            self._motors[i] = value
        if self.lib.jointspace_forward(self.handle, self._motors, self._xyz,
                                       self._error, ERROR_LEN):
            raise self.error(self._reason())
        return [self._xyz[0], self._xyz[1], self._xyz[2]]

    def inverse(self, pos, previous=None):
        """Motor positions of pos (angles nearest `previous`, a dict by motor, where given), or None."""
        for i in range(3):
            self._xyz[i] = pos[i]
        near = self.ffi.NULL
        if previous is not None:
            near = self.ffi.new("double[]", [previous.get(n, 0.) for n in self.motor_names])
        if self.lib.jointspace_inverse(self.handle, self._xyz, near, self._motors,
                                       self._error, ERROR_LEN):
            return None
        return [self._motors[i] for i in range(len(self.motor_names))]

    def check_move(self, start, end, speed, accel):
        """(caps, ends_at_rest): caps None when nothing binds, (speed, accel) when the move must be slowed;
        ends_at_rest when the move ends at a pose the arm may only rest at. Raises ValueError with the reason when
        the move cannot be made. speed <= 0 checks the segment only. Caps are positive and finite (Klipper's
        move.limit_speed divides by them): the library refuses a move its limits would allow no speed, and a cap
        that is not is refused here too."""
        rc = self.lib.jointspace_check_move(
            self.handle, start[0], start[1], start[2], end[0], end[1], end[2], speed, accel,
            self._limits, self._error, ERROR_LEN)
        if rc < 0:
            raise ValueError(self._reason())
        caps = (self._limits[0], self._limits[1]) if rc & 1 else None
        if caps is not None and not all(0. < c < float("inf") for c in caps):
            raise ValueError("the motor limits allow no speed along this move (caps %r)" % (caps,))
        return caps, bool(rc & 2)

    def junction_speed(self, prev_start, corner, prev_accel, next_end, next_accel):
        """The highest speed at the corner (inf where nothing caps it)."""
        for i, point in enumerate((prev_start, corner, next_end)):
            for k in range(3):
                self._corner[3 * i + k] = point[k]
        return self.lib.jointspace_junction_speed(self.handle, self._corner, prev_accel, next_accel)

    def declared_home(self):
        if self.lib.jointspace_declared_home(self.handle, self._xyz):
            return None
        return [self._xyz[0], self._xyz[1], self._xyz[2]]

    def reach_margin(self, pos):
        if self.lib.jointspace_reach_margin(self.handle, pos[0], pos[1], pos[2], self._margin):
            return None
        return self._margin[0]


######################################################################
# Kinematics
######################################################################

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
    """What Klipper's toolhead calls on a kinematics, shared by the polar and SCARA machines. Subclasses
    create the steppers in Klipper's order and say how the XY joints home."""

    def __init__(self, toolhead, config, name):
        self.printer = config.get_printer()
        self.toolhead = toolhead
        self.name = name
        self.machine = Machine(config)
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
        self.max_z_velocity = config.getfloat("max_z_velocity", self.max_velocity, above=0.,
                                              maxval=self.max_velocity)
        self.max_z_accel = config.getfloat("max_z_accel", self.max_accel, above=0.,
                                           maxval=self.max_accel)

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

    def __init__(self, toolhead, config):
        JointspaceKinematics.__init__(self, toolhead, config, "jointspace_polar")
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
        self.offsets = {
            "arm_zero_offset": config.getfloat("arm_zero_offset", 0.),
            "arm_lateral_offset": config.getfloat("arm_lateral_offset", 0.),
        }

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


class ScaraKinematics(JointspaceKinematics):
    """SCARA: shoulder motor (stepper_a), elbow motor (stepper_b, coupled to the shoulder), Z."""

    joint_names = ("stepper_a", "stepper_b")
    angle_motors = joint_names
    turning_motors = ()

    def __init__(self, toolhead, config):
        JointspaceKinematics.__init__(self, toolhead, config, "jointspace_scara")
        self.home_position = self.machine.declared_home()
        joints = []
        for name in self.joint_names:
            section = config.getsection(name)
            if section.get("endstop_pin", None, note_valid=False) is not None:
                joints.append(stepper.LookupMultiRail(section, units_in_radians=True))
                self.joint_rails[name] = joints[-1]
            elif self.home_position is not None:
                # FEKT-SCARA's homing declares the pose: a joint needs no endstop.
                joints.append(stepper.PrinterStepper(section, units_in_radians=True))
            else:
                raise config.error(
                    "jointspace_scara: [%s] needs endstop_pin (the joints home to endstops) "
                    "or [printer] needs home_position (the pose homing declares)" % (name,))
        self.rail_z = stepper.LookupMultiRail(config.getsection("stepper_z"))
        self.offsets = {k: config.getfloat(k, 0.) for k in ("offset_x", "offset_y")}
        self.printer.lookup_object("gcode").register_command(
            "JOINTSPACE_SCARA_PATTERN", self.cmd_JOINTSPACE_SCARA_PATTERN,
            desc=self.cmd_JOINTSPACE_SCARA_PATTERN_help)
        reach = config.getfloat("link1_length") + config.getfloat("link2_length")
        ox, oy = self.offsets["offset_x"], self.offsets["offset_y"]
        self._attach(toolhead, list(zip(self.joint_names, joints)) + [("stepper_z", self.rail_z)],
                     ((ox - reach, oy - reach), (ox + reach, oy + reach)))

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


    cmd_JOINTSPACE_SCARA_PATTERN_help = (
        "Print crosses at well-conditioned arm poses and write the measurements file to fill in "
        "(then: jointspace calibrate scara --measurements FILE)")

    def cmd_JOINTSPACE_SCARA_PATTERN(self, gcmd):
        poses = gcmd.get_int("POSES", 12, minval=4, maxval=64)
        cross = gcmd.get_float("CROSS", 6., above=1., maxval=30.)
        ffi, lib = self.machine.ffi, self.machine.lib
        gcode = ffi.new("char[]", 1 << 18)
        template = ffi.new("char[]", 1 << 16)
        count = lib.jointspace_scara_pattern(self.machine.handle, poses, cross, gcode, len(gcode),
                                             template, len(template))
        if count < 0:
            raise gcmd.error("jointspace: no pose of this arm fits a calibration cross (reach, limits)")
        config_file = self.printer.get_start_args().get("config_file", "printer.cfg")
        path = os.path.join(os.path.dirname(os.path.abspath(config_file)),
                            "jointspace-scara-measurements.csv")
        with open(path + ".tmp", "w") as f:
            f.write(ffi.string(template).decode())
        os.replace(path + ".tmp", path)
        gcmd.respond_info(
            "jointspace: printing %d crosses. Measure each cross centre on the bed (mm), fill in x_mm and y_mm "
            "in %s, then run: jointspace calibrate scara -c printer.cfg --measurements %s" % (count, path, path))
        self.printer.lookup_object("gcode").run_script_from_command(ffi.string(gcode).decode())


def load_kinematics_polar(toolhead, config):
    return PolarKinematics(toolhead, config)


def load_kinematics_scara(toolhead, config):
    return ScaraKinematics(toolhead, config)


######################################################################
# [jointspace]: register the kinematics modules
######################################################################

def _register(name, loader):
    module = types.ModuleType(name)
    module.load_kinematics = loader
    for prefix in ("kinematics.", "klippy.kinematics."):
        sys.modules[prefix + name] = module


MAX_WAYPOINTS = 4096


class MoveSplitter:
    """The toolhead's move, wrapped. It checks each move whole before any part of it is queued (a refused move
    moves nothing), turns a polar bed in place on a circle of the centre's tolerance where a move passes through the
    centre or leaves it in a new direction, ends a move that ends within that circle on the centre itself, and (with
    cut_spans) cuts each move where jointspace's planner limits change (near the polar centre, SCARA singular poses,
    step-rate limits), so check_move caps only the pieces that need it. G-code transforms (bed_mesh,
    skew_correction...) come first, as they end in the toolhead's move."""

    def __init__(self, printer, kin, cut_spans):
        self.printer = printer
        self.kin = kin
        self.cut_spans = 1 if cut_spans else 0
        self.toolhead = printer.lookup_object("toolhead")
        machine = kin.machine
        self.ffi, self.lib, self.handle = machine.ffi, machine.lib, machine.handle
        self.buffer = self.ffi.new("double[]", 3 * MAX_WAYPOINTS)
        self.error = self.ffi.new("char[]", ERROR_LEN)
        self.centre = machine.centre
        # Only a polar bed's whole turns need following.
        self.note_xy = kin.note_xy if machine.has_centre else (lambda pos: None)
        # Every toolhead move passes here, not only G-code's: probing, Z_TILT_ADJUST, bed_mesh's segments and other
        # extras move the toolhead directly, and a move leaving the polar centre must turn the bed in place whoever
        # asked for it. (Set at klippy:connect, before gcode_move binds the toolhead's move at klippy:ready.)
        self.toolhead_move = self.toolhead.move
        self.toolhead.move = self.move

    def move(self, newpos, speed):
        if self.kin.joint_space:
            # Homing in joint space: X and Y stand for joint readings.
            self.toolhead_move(newpos, speed)
            return
        start = self.toolhead.get_position()
        if (newpos[0] == start[0] and newpos[1] == start[1]) or not (
                self.cut_spans or self._meets_centre(start, newpos)):
            # Nothing to cut: the move goes whole, and check_move refuses or caps it whole.
            self.toolhead_move(newpos, speed)
            self.note_xy(newpos)
            return
        count = self.lib.jointspace_move_waypoints(
            self.handle, start[0], start[1], start[2], newpos[0], newpos[1], newpos[2], speed,
            self.toolhead.max_accel, self.kin.turn_angle or 0., self.cut_spans, self.buffer, MAX_WAYPOINTS,
            self.error, ERROR_LEN)
        if count == -2:
            self.kin.refuse_unreachable(start, newpos, self.ffi.string(self.error).decode())
        if count < 1:
            # More pieces than worth it: the move stays whole and check_move caps it.
            self.toolhead_move(newpos, speed)
            self.note_xy(newpos)
            return
        if count > 1:
            # Homed, Z in range: asked of the whole move before any piece is queued.
            self.kin.refuse_unreachable(start, newpos)
        b = self.buffer
        for i in range(count):
            f = b[3 * i + 2]
            rest = newpos[2:] if i == count - 1 else [s + (e - s) * f for s, e in zip(start[2:], newpos[2:])]
            pos = [b[3 * i], b[3 * i + 1]] + list(rest)
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


class Jointspace:
    def __init__(self, config):
        self.printer = config.get_printer()
        # Fail early, naming the path, if the library is missing or was built for another host.
        ffi, lib = load_library(config)
        self.version = ffi.string(lib.jointspace_version()).decode()
        self.split_moves = config.getboolean("split_moves", True)
        self.splitter = None
        _register("jointspace_polar", load_kinematics_polar)
        _register("jointspace_scara", load_kinematics_scara)
        self.printer.register_event_handler("klippy:connect", self._handle_connect)
        # The Hall-sensor centre scan, for a polar bed with magnets and a sensor on the arm.
        self.centre_scan = None
        if config.get("hall_pin", None) is not None:
            self.centre_scan = jointspace_scan.HallCentreScan(config, (ffi, lib))

    def _handle_connect(self):
        kin = self.printer.lookup_object("toolhead").get_kinematics()
        if not isinstance(kin, JointspaceKinematics):
            return
        # centre_slowdown: klipper plans as Klipper's own polar does, whole moves only; a bed with a centre still
        # turns in place there (a move cannot turn it half a revolution at one instant).
        cut_spans = self.split_moves and kin.centre_slowdown == "exact"
        if cut_spans or kin.machine.has_centre:
            self.splitter = MoveSplitter(self.printer, kin, cut_spans)

    def get_status(self, eventtime):
        status = {"version": self.version,
                  "split_moves": self.splitter is not None and bool(self.splitter.cut_spans)}
        if self.centre_scan is not None:
            status["centre_scan"] = self.centre_scan.last_result
        return status


def load_config(config):
    return Jointspace(config)
