# jointspace loader for Klipper and Kalico: [jointspace] in printer.cfg loads the jointspace plug-in
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See the LICENSE file of the jointspace_klipper package.
#
# jointspace-klipper: written by install.sh
# jointspace's klipper/install.sh copied this file here (klipper/install.sh --uninstall removes it, found by the
# line above). The plug-in is the jointspace-klipper package in Klipper's Python environment: updating it (Moonraker,
# pip) changes nothing here.
import sys

try:
    import jointspace_klipper
except ImportError as e:
    _MISSING = str(e)

    def load_config(config):
        raise config.error(
            "jointspace: the jointspace-klipper package is not installed in %s (%s): install it with "
            "jointspace's klipper/install.sh (or %s -m pip install jointspace-klipper) and restart, or remove "
            "[jointspace] from printer.cfg" % (sys.prefix, _MISSING, sys.executable))
else:
    load_config = jointspace_klipper.load(__name__).load_config
