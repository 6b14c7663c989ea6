# jointspace: G-code commands of the [jointspace] section
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# JOINTSPACE_SCARA_PATTERN: crosses at well-conditioned arm poses, and the measurements file to fill in for
# `jointspace calibrate scara`. The poses and the G-code come from the library (the machine's reach and limits).
# (JOINTSPACE_SCAN_CENTRE lives with its ADC set-up in jointspace_scan.py.)
import os

MEASUREMENTS_FILE = "jointspace-scara-measurements.csv"


class JointspaceCommands:
    def __init__(self, config):
        self.printer = config.get_printer()
        self.printer.lookup_object("gcode").register_command(
            "JOINTSPACE_SCARA_PATTERN", self.cmd_JOINTSPACE_SCARA_PATTERN,
            desc=self.cmd_JOINTSPACE_SCARA_PATTERN_help)

    def _machine(self, gcmd, kinematics, command):
        # The kinematics' machine, once [printer] has loaded it; commands for another machine say which they need.
        kin = self.printer.lookup_object("toolhead").get_kinematics()
        if getattr(kin, "name", None) != kinematics:
            raise gcmd.error("jointspace: %s needs kinematics: %s" % (command, kinematics))
        return kin.machine

    def _write_beside_config(self, name, text):
        # Beside printer.cfg, whole or not at all.
        config_file = self.printer.get_start_args().get("config_file", "printer.cfg")
        path = os.path.join(os.path.dirname(os.path.abspath(config_file)), name)
        with open(path + ".tmp", "w") as f:
            f.write(text)
        os.replace(path + ".tmp", path)
        return path

    cmd_JOINTSPACE_SCARA_PATTERN_help = (
        "Print crosses at well-conditioned arm poses and write the measurements file to fill in "
        "(then: jointspace calibrate scara --measurements FILE)")

    def cmd_JOINTSPACE_SCARA_PATTERN(self, gcmd):
        machine = self._machine(gcmd, "jointspace_scara", "JOINTSPACE_SCARA_PATTERN")
        poses = gcmd.get_int("POSES", 20, minval=4, maxval=64)
        cross = gcmd.get_float("CROSS", 6., above=1., maxval=30.)
        count, gcode, template = machine.scara_pattern(poses, cross)
        if count < 0:
            raise gcmd.error("jointspace: no pose of this arm fits a calibration cross (reach, limits)")
        path = self._write_beside_config(MEASUREMENTS_FILE, template)
        gcmd.respond_info(
            "jointspace: printing %d crosses. Measure each cross centre on the bed (mm), fill in x_mm and y_mm "
            "in %s, then run: jointspace calibrate scara -c printer.cfg --measurements %s" % (count, path, path))
        self.printer.lookup_object("gcode").run_script_from_command(gcode)
