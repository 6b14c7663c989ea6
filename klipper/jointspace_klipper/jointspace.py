# jointspace kinematics for Klipper and Kalico: SCARA arms, five-bar (parallel) SCARAs and polar printers
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# Loaded from a [jointspace] config section (klippy/extras/ on Klipper, klippy/plugins/ on Kalico: the loader of the
# installed jointspace-klipper package, or from a source tree a link to this file), it registers the kinematics
# "jointspace_polar", "jointspace_scara" and "jointspace_fivebar" before [printer] imports them. The machine itself
# (geometry, offsets, limits, reach) lives in libjointspace_klipper.so, built from the same printer.cfg keys the
# jointspace command line reads; Klipper's itersolve calls that library for every step.
#
# The plug-in's modules, all beside this file's real path:
#   jointspace_library.py     the library: loading and its checks, the host's arithmetic, the Machine it builds
#   jointspace_kinematics.py  Klipper's kinematics interface over that machine (polar, SCARA, five-bar)
#   jointspace_splitter.py    MoveSplitter, the move transform wrapping the toolhead's move
#   jointspace_commands.py    JOINTSPACE_SCARA_PATTERN
#   jointspace_scan.py        JOINTSPACE_SCAN_CENTRE, the Hall-sensor centre scan
import importlib.util
import os
import sys
import types

HERE = os.path.dirname(os.path.realpath(__file__))
# The package the host loaded this file into ("extras", Kalico's "klippy.extras"), for the siblings' names.
PACKAGE = __name__.rpartition(".")[0]


def _load_sibling(name):
    # By path, from beside the real file (the installed package, or the source tree's folder): the hosts load this file
    # under different package names (Kalico's plugins as klippy.extras.*), so a relative import would look in the
    # wrong package. Named inside this file's package, so a sibling tells Kalico from Klipper as this file does.
    qualified = PACKAGE + "." + name if PACKAGE else name
    spec = importlib.util.spec_from_file_location(qualified, os.path.join(HERE, name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


library = _load_sibling("jointspace_library")
kinematics = _load_sibling("jointspace_kinematics")
jointspace_splitter = _load_sibling("jointspace_splitter")
jointspace_commands = _load_sibling("jointspace_commands")
jointspace_scan = _load_sibling("jointspace_scan")


def load_kinematics_polar(toolhead, config):
    return kinematics.PolarKinematics(toolhead, config, library.Machine(config))


def load_kinematics_scara(toolhead, config):
    return kinematics.ScaraKinematics(toolhead, config, library.Machine(config))


def load_kinematics_fivebar(toolhead, config):
    return kinematics.FivebarKinematics(toolhead, config, library.Machine(config))


def _register(name, loader):
    # As the module Klipper imports for `kinematics: NAME` (Kalico's package is klippy.kinematics).
    module = types.ModuleType(name)
    module.load_kinematics = loader
    for prefix in ("kinematics.", "klippy.kinematics."):
        sys.modules[prefix + name] = module


class Jointspace:
    def __init__(self, config):
        self.printer = config.get_printer()
        # Fail early, naming the path, if the library is missing or was built for another host.
        ffi, lib = library.load_library(config)
        # "jointspace-klipper X.Y.Z" and the commit it was built from, for printer.jointspace (Mainsail, macros).
        self.version = ffi.string(lib.jointspace_version()).decode().rpartition(" ")[2]
        self.commit = ffi.string(lib.jointspace_commit()).decode()
        self.splitter = jointspace_splitter.MoveSplitter(config, kinematics.JointspaceKinematics)
        _register("jointspace_polar", load_kinematics_polar)
        _register("jointspace_scara", load_kinematics_scara)
        _register("jointspace_fivebar", load_kinematics_fivebar)
        self.commands = jointspace_commands.JointspaceCommands(config)
        # The Hall-sensor centre scan, for a polar bed with magnets and a sensor on the arm.
        self.centre_scan = None
        if config.get("hall_pin", None) is not None:
            self.centre_scan = jointspace_scan.HallCentreScan(config, (ffi, lib))

    def get_status(self, eventtime):
        status = {"version": self.version, "commit": self.commit,
                  "split_moves": self.splitter.active and bool(self.splitter.cut_spans)}
        if self.centre_scan is not None:
            status["centre_scan"] = self.centre_scan.last_result
        return status


def load_config(config):
    return Jointspace(config)
