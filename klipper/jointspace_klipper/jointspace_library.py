# jointspace: libjointspace_klipper.so loaded into the host, and the machine it builds
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# The library is loaded into the host's own cffi instance (its stepper_kinematics pointers are then the ones the
# host's stepper code accepts), after these checks: it is this plug-in's version, built from this folder's
# jointspace.h, and its layout of struct stepper_kinematics and struct move is the one the running host's own
# klippy/chelper headers declare; then the host's arithmetic (plain or fused multiply-add) is learned so that step
# times agree to the bit. `Machine` is the machine the library builds from printer.cfg and every question asked of it;
# nothing else in the plug-in calls the library's machine functions.
import logging
import math
import os
import re

if __name__.startswith("klippy."):
    from klippy import chelper
else:
    import chelper

HERE = os.path.dirname(os.path.realpath(__file__))
LIBRARY_NAME = "libjointspace_klipper.so"
ERROR_LEN = 512
MAX_WAYPOINTS = 4096


######################################################################
# Loading and checking the library
######################################################################

def _cdef_text():
    # The C interface, from jointspace.h (preprocessor lines dropped: cffi reads declarations only).
    with open(os.path.join(HERE, "jointspace.h")) as f:
        return "".join(l for l in f if not l.lstrip().startswith("#"))


# Where the plug-in's own library is: in the installed package (the wheel: maturin names it after the package's
# `native` module), beside the modules, or in the source tree's cargo build (install.sh --dev).
PACKAGED_LIBRARIES = (os.path.join("native", "libnative.so"), LIBRARY_NAME,
                      os.path.join("..", "..", "target", "release", LIBRARY_NAME))
REINSTALL = "reinstall the plug-in with jointspace's klipper/install.sh"


def _packaged_library():
    # The library installed with this plug-in, or None.
    for relative in PACKAGED_LIBRARIES:
        path = os.path.join(HERE, relative)
        if os.path.isfile(path):
            return os.path.realpath(path)
    return None


def _library_path(config):
    # A path the owner gave must exist: silently loading another library would hide a mistake. printer.cfg is
    # trusted as Klipper's code is (the library runs inside Klipper); the checks after loading catch a wrong build.
    given = [("[jointspace] library", config.get("library", None)
              if config.get_name() == "jointspace" else None),
             ("the environment variable JOINTSPACE_LIBRARY", os.environ.get("JOINTSPACE_LIBRARY"))]
    packaged = _packaged_library()
    for where, path in given:
        if path:
            if not os.path.isfile(path):
                raise config.error(
                    "jointspace: %s names %s, which does not exist (remove the setting to use the library this "
                    "plug-in was installed with)" % (where, path))
            if packaged and os.path.realpath(path) != packaged:
                logging.info("jointspace: %s names %s instead of the plug-in's own %s", where, path, packaged)
            return os.path.realpath(path)
    if packaged:
        return packaged
    raise config.error(
        "jointspace: %s not found beside %s (%s, or set [jointspace] library: /path/to/%s)"
        % (LIBRARY_NAME, HERE, REINSTALL, LIBRARY_NAME))


def _header_hash():
    # FNV-1a of jointspace.h, as the library computes it of the header it was built from.
    with open(os.path.join(HERE, "jointspace.h"), "rb") as f:
        data = f.read()
    value = 0xcbf29ce484222325
    for byte in bytearray(data):
        value = ((value ^ byte) * 0x100000001b3) & 0xffffffffffffffff
    return value


def _open(config, ffi, path):
    # A file the loader cannot open (not a shared library, another platform's) is the owner's to fix: a config error.
    try:
        return ffi.dlopen(path)
    except OSError as e:
        raise config.error("jointspace: cannot load %s as a library: %s" % (path, e))


def _header_version():
    # The version the header belongs to (its JOINTSPACE_VERSION line; the library refuses to build otherwise).
    with open(os.path.join(HERE, "jointspace.h")) as f:
        match = re.search(r'^#define JOINTSPACE_VERSION "([^"]*)"', f.read(), re.M)
    return match.group(1) if match else "?"


def _check_version(config, ffi, lib, path):
    # First, as the plainest reason: a library of another release (or not ours at all) is refused by name.
    try:
        theirs = ffi.string(lib.jointspace_version()).decode(errors="replace")
    except AttributeError:
        theirs = "no jointspace version"
    ours = "jointspace-klipper " + _header_version()
    if theirs != ours:
        raise config.error(
            "jointspace: %s is %s, this plug-in is %s: %s and restart" % (path, theirs, ours, REINSTALL))


def _check_built_from_this_header(config, lib, path):
    try:
        theirs = lib.jointspace_header_hash()
    except AttributeError:
        theirs = None
    if theirs != _header_hash():
        raise config.error(
            "jointspace: %s was built from another version of jointspace.h than this plug-in's: %s (from a "
            "source tree: cargo build --release -p klipper) and restart" % (path, REINSTALL))


# Klipper's headers that declare the structs the library shares with the host (list.h: struct move's list node).
HOST_HEADERS = ("list.h", "itersolve.h", "trapq.h")
# The library reads or writes these; its layout of each must be the host's.
SHARED_STRUCTS = (("stepper_kinematics", "itersolve.h"), ("move", "trapq.h"))
# The host's declarations are handed to its cffi renamed, beside (never instead of) its own opaque ones.
HOST_PREFIX = "jointspace_host_"


def _c_items(text):
    """The top-level declarations of C header text, each ending in ';' (comments, preprocessor lines and function
    bodies dropped)."""
    text = re.sub(r"/\*.*?\*/", " ", text.replace("\\\n", " "), flags=re.S)
    text = "\n".join(l for l in re.sub(r"//[^\n]*", "", text).splitlines()
                     if not l.lstrip().startswith("#"))
    items, depth, start = [], 0, 0
    for i, c in enumerate(text):
        if c == "{":
            depth += 1
        elif c == "}":
            depth -= 1
            if depth == 0 and "(" in text[start:i].split("{", 1)[0]:
                start = i + 1  # the end of a function's body (list.h's inline helpers)
        elif c == ";" and depth == 0:
            items.append(text[start:i + 1].strip())
            start = i + 1
    return items


def _is_type_declaration(item):
    # Structs, unions, named enums and typedefs: what a struct's layout can depend on (no functions, no constants).
    if item.startswith("typedef"):
        return True
    head = item.split("{", 1)[0]
    return re.match(r"(struct|union|enum)\s+\w", item) is not None and "(" not in head


def _renamed(declarations):
    # Every tag and typedef name prefixed, so they cannot clash with the host's own cdef.
    text = re.sub(r"\b(struct|union|enum)\s+(\w+)", r"\1 " + HOST_PREFIX + r"\2", declarations)
    for item in _c_items(text):
        if item.startswith("typedef"):
            name = re.search(r"\(\s*\*\s*(\w+)\s*\)|(\w+)\s*(\[[^]]*\]\s*)*;$", item)
            if name:
                old = name.group(1) or name.group(2)
                text = re.sub(r"\b%s\b" % (old,), HOST_PREFIX + old, text)
    return text


def _host_version(config):
    # The host's own name for its version (git describe, "?" when run from a tree without git).
    name = "Kalico" if __name__.startswith("klippy.") else "Klipper"
    version = config.get_printer().get_start_args().get("software_version") or "?"
    return "%s version %r" % (name, version)


def _declare_host_structs(config, ffi):
    """Hands the host's own declarations of the shared structs (its klippy/chelper headers, as it compiled its
    step generator from them) to its cffi, under HOST_PREFIX names; the chelper folder."""
    folder = os.path.dirname(os.path.realpath(chelper.__file__))
    declarations = []
    try:
        for header in HOST_HEADERS:
            with open(os.path.join(folder, header)) as f:
                declarations += [i for i in _c_items(f.read()) if _is_type_declaration(i)]
        ffi.cdef(_renamed("\n".join(declarations)))
    except Exception as e:
        raise config.error(
            "jointspace: cannot read the struct layouts of %s from %s (%s): the plug-in does not know this host"
            % (_host_version(config), folder, e))
    return folder


def _host_layout(ffi, name):
    # (size, {field: (offset, size)}) of the host's struct `name`, as its header declares it on this platform.
    t = ffi.typeof("struct " + HOST_PREFIX + name)
    return ffi.sizeof(t), {f: (d.offset, ffi.sizeof(d.type)) for f, d in t.fields}


def _library_layout(ffi, lib, name):
    # (size or None, {field: (offset, size)}): the library's idea of the struct (jointspace_struct_layout).
    size, fields = None, {}
    for line in ffi.string(lib.jointspace_struct_layout(name.encode())).decode().splitlines():
        words = line.split()
        if words[0] == "size":
            size = int(words[1])
        else:
            fields[words[0]] = (int(words[1]), int(words[2]))
    return size, fields


def _layout_differences(library, host):
    """What differs between the library's layout of a struct and the host's, as phrases in the host's field order
    (none when they agree). With a size, the library allocates the struct: the fields must be exactly the host's."""
    (size, fields), (host_size, host_fields) = library, host
    found = []
    for field, (offset, width) in fields.items():
        if field not in host_fields:
            found.append((offset, "no field %s (the library's at offset %d)" % (field, offset)))
        elif host_fields[field] != (offset, width):
            found.append((host_fields[field][0], "%s at offset %d size %d, the library's at %d size %d"
                          % ((field,) + host_fields[field] + (offset, width))))
    if size is not None:
        found += [(host_fields[f][0], "field %s at offset %d, unknown to the library" % (f, host_fields[f][0]))
                  for f in host_fields if f not in fields]
    out = ["size %d, the library's %d" % (host_size, size)] if size not in (None, host_size) else []
    return out + [phrase for _, phrase in sorted(found)]


def _summary(differences, shown=3):
    # The first few, as one field moved shifts every later one.
    more = len(differences) - shown
    return "; ".join(differences[:shown]) + ("; and %d more" % (more,) if more > 0 else "")


def _check_host_structs(config, ffi, lib, path):
    # Klipper's step generator and the library share two structs: a host whose headers lay either out otherwise
    # would load and step with wrong offsets, so it is refused here, before any stepper exists.
    folder = _declare_host_structs(config, ffi)
    for name, header in SHARED_STRUCTS:
        differences = _layout_differences(_library_layout(ffi, lib, name), _host_layout(ffi, name))
        if differences:
            raise config.error(
                "jointspace: %s declares struct %s (%s) otherwise than %s (%s) was built for: %s. It would step "
                "with wrong offsets: use a jointspace release that supports this host version"
                % (_host_version(config), name, os.path.join(folder, header), path,
                   ffi.string(lib.jointspace_version()).decode(), _summary(differences)))


_LIBRARY = {}
SK = "struct " + HOST_PREFIX + "stepper_kinematics *"


def _sample_moves(ffi, move, count):
    # Fixed pseudo-random moves (a 64-bit LCG): the same probe on every start. Yields a time into each move.
    # The positions through double views: the layout check found each struct coord to be three doubles.
    start_pos = ffi.cast("double *", ffi.addressof(move, "start_pos"))
    axes_r = ffi.cast("double *", ffi.addressof(move, "axes_r"))
    state = 12345
    for _ in range(count):
        values = []
        for _ in range(9):
            state = (state * 6364136223846793005 + 1442695040888963407) % (1 << 64)
            values.append((state >> 11) / float(1 << 53))
        move.move_t = 1. + values[0]
        move.start_v = 300. * values[1]
        move.half_accel = 1500. * (values[2] - .5)
        start_pos[0], start_pos[1] = 600. * (values[3] - .5), 600. * (values[4] - .5)
        axes_r[0] = values[5] - .5
        axes_r[1] = math.sqrt(max(0., 1. - axes_r[0] ** 2)) * (1 if values[6] > .5 else -1)
        yield values[7] * move.move_t


def _host_arithmetic(ffi, lib):
    """Whether the host's C helper rounds like fused multiply-adds (Kalico compiles it with -march=native):
    the host's own polar arm solver and ours, in both arithmetics, on sample moves. Our solvers then compute
    positions exactly as the host's would, so step times agree to the bit. None when neither matches."""
    host_lib = chelper.get_ffi()[1]
    sk = ffi.gc(host_lib.polar_stepper_alloc(b"r"), host_lib.free)
    calc = ffi.cast("double (*)(void *, void *, double)", ffi.cast(SK, sk).calc_position_cb)
    move = ffi.new("struct " + HOST_PREFIX + "move *")
    matches = {0: True, 1: True}
    for t in _sample_moves(ffi, move, 400):
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
        lib = _open(config, ffi, path)
        _check_version(config, ffi, lib, path)
        _check_built_from_this_header(config, lib, path)
        _check_host_structs(config, ffi, lib, path)
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


######################################################################
# The machine
######################################################################

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


def _new_machine(config, ffi, lib, error):
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
    return ffi.gc(handle, lib.jointspace_machine_free)


class Machine:
    """The library's machine for this printer.cfg, and the questions asked of it."""

    def __init__(self, config):
        self.ffi, self.lib = load_library(config)
        ffi, lib = self.ffi, self.lib
        self.config_error = config.error
        self._error = ffi.new("char[]", ERROR_LEN)
        self.handle = _new_machine(config, ffi, lib, self._error)
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
        self._value = ffi.new("double *")
        self._waypoints = ffi.new("double[]", 3 * MAX_WAYPOINTS)
        # Asked once: most machines have no acceleration-limited motor, and then no corner needs capping.
        self.caps_corners = bool(lib.jointspace_caps_corners(self.handle))
        # A polar bed's centre (x, y, the tolerance within which a path meets it), or None.
        centre = ffi.new("double[3]")
        self.centre = (list(centre) if lib.jointspace_rotation_centre(self.handle, centre) == 0
                       else None)
        self.has_centre = self.centre is not None

    # -- solvers ----------------------------------------------------------------------------------
    def stepper_kinematics(self, name):
        sk = self.lib.jointspace_stepper_alloc(self.handle, name.encode())
        if sk == self.ffi.NULL:
            raise self.config_error("jointspace: no solver for %s" % (name,))
        return self.ffi.gc(sk, chelper.get_ffi()[1].free)

    def commanded(self, sk):
        return self.ffi.cast(SK, sk).commanded_pos

    def set_commanded(self, sk, value):
        self.ffi.cast(SK, sk).commanded_pos = value

    def linear_stepper_kinematics(self, cx, cy, cz):
        sk = self.lib.jointspace_linear_stepper_alloc(cx, cy, cz, _LIBRARY["fused"])
        return self.ffi.gc(sk, chelper.get_ffi()[1].free)

    # -- what the machine was built with ----------------------------------------------------------
    def value(self, key):
        """The value the machine was built with for a [printer] key (offset_x, link1_length, arm_zero_offset,
        max_z_velocity...), so the plug-in never reads a key a second time; None where it has no such key."""
        if self.lib.jointspace_machine_value(self.handle, key.encode(), self._value):
            return None
        return self._value[0]

    def declared_home(self):
        if self.lib.jointspace_declared_home(self.handle, self._xyz):
            return None
        return [self._xyz[0], self._xyz[1], self._xyz[2]]

    # -- geometry ---------------------------------------------------------------------------------
    def error(self, message):
        # At run time (not config time): what Klipper does with an error it does not expect.
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

    def reach_margin(self, pos):
        if self.lib.jointspace_reach_margin(self.handle, pos[0], pos[1], pos[2], self._value):
            return None
        return self._value[0]

    # -- moves ------------------------------------------------------------------------------------
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

    def waypoints(self, start, end, speed, accel, bed_angle, cut_spans):
        """(count, buffer): where the move transform cuts start -> end, as x, y, fraction triples in buffer (valid
        until the next call). count -1: more pieces than worth it; -2: refused, the reason in waypoint_error()."""
        count = self.lib.jointspace_move_waypoints(
            self.handle, start[0], start[1], start[2], end[0], end[1], end[2], speed, accel, bed_angle,
            cut_spans, self._waypoints, MAX_WAYPOINTS, self._error, ERROR_LEN)
        return count, self._waypoints

    def waypoint_error(self):
        return self._reason()

    # -- calibration ------------------------------------------------------------------------------
    def scara_pattern(self, poses, cross):
        """(count, G-code, measurements template) of a SCARA calibration pattern; count < 0 when no pose fits."""
        gcode = self.ffi.new("char[]", 1 << 18)
        template = self.ffi.new("char[]", 1 << 16)
        count = self.lib.jointspace_scara_pattern(self.handle, poses, cross, gcode, len(gcode),
                                                  template, len(template))
        if count < 0:
            return count, None, None
        return count, self.ffi.string(gcode).decode(), self.ffi.string(template).decode()
