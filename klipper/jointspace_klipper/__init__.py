# jointspace-klipper: jointspace's kinematics for Klipper and Kalico, as a package in the host's Python environment
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# Installed with pip into Klipper's virtualenv (klipper/install.sh, Moonraker's `type: python` updater); the host
# loads it through the small loader install.sh writes into klippy/extras/ (Kalico: klippy/plugins/), a copy of
# loader.py. Nothing here runs on import but path arithmetic: the plug-in is loaded by `load`, inside the host.
import importlib.util
import os

HERE = os.path.dirname(os.path.realpath(__file__))
# What install.sh copies into the host tree: the loader, and the stand-in for klippy/kinematics/jointspace_*.py.
LOADER = os.path.join(HERE, "loader.py")
MISSING_SECTION = os.path.join(HERE, "jointspace_missing_section.py")


def load(loader_name):
    """The plug-in's main module (jointspace.py of this package), loaded for the host's loader module named
    `loader_name` ("extras.jointspace", Kalico's "klippy.extras.jointspace"): named in the loader's package, so the
    plug-in's modules tell Kalico from Klipper by their package, as when they are linked into the host's tree."""
    package = loader_name.rpartition(".")[0]
    name = (package + "." if package else "") + "jointspace_plugin"
    spec = importlib.util.spec_from_file_location(name, os.path.join(HERE, "jointspace.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
