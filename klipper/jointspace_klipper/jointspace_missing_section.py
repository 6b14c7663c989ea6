# jointspace kinematics named without the [jointspace] section that loads them
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# jointspace-klipper: written by install.sh
# install.sh copies (or, from a source tree, links) this file as klippy/kinematics/jointspace_polar.py,
# jointspace_scara.py and jointspace_fivebar.py; --uninstall removes the copies, found by the line above. Klipper imports it only when
# printer.cfg names one of those kinematics and has no [jointspace] section: that section loads jointspace.py, which
# registers the real kinematics before [printer] imports them.


def load_kinematics(toolhead, config):
    raise config.error(
        "kinematics: %s needs a [jointspace] section in printer.cfg, which loads the jointspace plug-in: "
        "add a line [jointspace] and restart" % (config.get("kinematics"),))
