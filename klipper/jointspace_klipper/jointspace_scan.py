# jointspace: the polar bed's rotation centre from a Hall-sensor scan of the bed's magnets
#
# Copyright (C) 2026  The jointspace developers
#
# This file may be distributed under the terms of the GNU GPLv3 license, or (at your option) any later
# version. See LICENSE in this folder.
#
# JOINTSPACE_SCAN_CENTRE: the arm stops at a series of radii across the magnet ring, on both sides of the
# centre, and at each the bed turns one full revolution while the MCU's ADC reports the sensor. Each report's
# arm and bed readings come from the steppers' position history at its own time; the library
# (libjointspace_klipper.so, calibrate::sweep) finds the magnets' centres, fits arm_zero_offset and
# arm_lateral_offset, and writes the detections file `jointspace calibrate centre --scan` reads.
import math
import os

SAMPLE_COUNT = 4          # ADC conversions averaged per report
SAMPLE_TIME = 0.0002      # s between them
CSV_LEN = 1 << 16
REPORT_LEN = 1 << 13
MAX_PASSES = 4096


class HallCentreScan:
    def __init__(self, config, library):
        self.printer = config.get_printer()
        self.ffi, self.lib = library
        self.settings = self._settings(config)
        self.speed = config.getfloat("hall_speed", 50., above=0.)
        self.accel = config.getfloat("hall_accel", 500., above=0.)
        report_time = config.getfloat("hall_report_time", 0.002, minval=0.0005)
        self.samples = None  # (print time, arm mm, bed rad, adc) while a scan records
        self.last_result = {}  # the last accepted scan, for the printer's status (Mainsail, Moonraker)
        adc = self.printer.lookup_object("pins").setup_pin("adc", config.get("hall_pin"))
        if hasattr(adc, "setup_adc_sample"):
            # Klipper: reports arrive as lists of (time, value).
            adc.setup_adc_sample(report_time, SAMPLE_TIME, SAMPLE_COUNT)
            adc.setup_adc_callback(self._reports)
        else:
            # Kalico and the FEKT fork: one (time, value) per call.
            adc.setup_minmax(SAMPLE_TIME, SAMPLE_COUNT)
            adc.setup_adc_callback(report_time, lambda t, v: self._reports([(t, v)]))
        self.printer.lookup_object("gcode").register_command(
            "JOINTSPACE_SCAN_CENTRE", self.cmd_JOINTSPACE_SCAN_CENTRE,
            desc=self.cmd_JOINTSPACE_SCAN_CENTRE_help)

    def _settings(self, config):
        reference = config.getfloat("hall_adc_reference", 3.3, above=0.)
        s = self.ffi.new("struct jointspace_hall_scan *")
        s.magnet_count = config.getint("hall_magnets", 16, minval=3)
        s.ring_radius = config.getfloat("hall_ring_radius", above=0.)
        s.max_offset = config.getfloat("hall_max_offset", 2., minval=0.)
        s.pass_pitch = config.getfloat("hall_pass_pitch", 0.5, above=0.)
        s.field_reach = config.getfloat("hall_field_reach", 4., above=0.)
        s.threshold = config.getfloat("hall_threshold", 10., above=0.) * 1e-3  # mT -> T
        s.adc_reference = reference
        # mV/mT; a ratiometric 49E gives 16 at 5 V, and is powered from the ADC's own rail.
        s.sensitivity = config.getfloat("hall_sensitivity", 16. * reference / 5., above=0.)
        s.saturation = config.getfloat("hall_saturation", 100., above=0.) * 1e-3
        s.max_sigma = config.getfloat("hall_max_sigma", 0.01, above=0.)
        s.sensor_alignment = config.getfloat("hall_sensor_alignment", 0.05, minval=0.)
        return s

    def _reports(self, reports):
        # Converted at once: Klipper keeps the steppers' position history for 30 s only.
        if self.samples is None:
            return
        for t, value in reports:
            self.samples.append((t, self._reading(self.arm, t), self._reading(self.bed, t), value))

    @staticmethod
    def _reading(stepper, print_time):
        return stepper.mcu_to_commanded_position(stepper.get_past_mcu_position(print_time))

    def _passes(self):
        arms = self.ffi.new("double[]", MAX_PASSES)
        overlap = self.ffi.new("double *")
        error = self.ffi.new("char[]", REPORT_LEN)
        count = self.lib.jointspace_scan_passes(self.settings, arms, MAX_PASSES, overlap, error,
                                                REPORT_LEN)
        if count < 0:
            raise self.printer.command_error(
                "jointspace: %s" % (self.ffi.string(error).decode() or "too many passes",))
        return [arms[i] for i in range(count)], math.degrees(overlap[0])

    cmd_JOINTSPACE_SCAN_CENTRE_help = (
        "Scan the bed's magnets with the Hall sensor and fit arm_zero_offset / arm_lateral_offset "
        "(then SAVE_CONFIG)")

    def cmd_JOINTSPACE_SCAN_CENTRE(self, gcmd):
        toolhead = self.printer.lookup_object("toolhead")
        kin = toolhead.get_kinematics()
        if getattr(kin, "name", None) != "jointspace_polar":
            raise gcmd.error("jointspace: JOINTSPACE_SCAN_CENTRE needs kinematics: jointspace_polar")
        if "xy" not in kin.homed:
            raise gcmd.error("jointspace: home the printer first (G28)")
        arms, overlap_deg = self._passes()
        arm_rail = kin.joint_rails["stepper_arm"]
        low, high = arm_rail.get_range()
        if min(arms) < low or max(arms) > high:
            raise gcmd.error(
                "jointspace: the scan needs the arm from %.1f to %.1f mm (past the centre), stepper_arm allows "
                "%.1f to %.1f: lower position_min" % (min(arms), max(arms), low, high))
        self.arm = arm_rail.get_steppers()[0]
        self.bed = dict(kin.motor_steppers)["stepper_bed"]
        windows = self._sweep(toolhead, kin, arms, overlap_deg)
        rows = [(i, arm, bed, value) for (t, arm, bed, value) in self.samples
                for i, (t0, t1) in enumerate(windows) if t0 <= t <= t1]
        self.samples = None
        self._write_samples(rows)
        self._fit(gcmd, rows, len(arms))

    def _sweep(self, toolhead, kin, arms, overlap_deg):
        """Runs the passes in joint space (X: arm mm, Y: bed degrees) and returns each pass's print-time span.
        Records the ADC reports from the first pass until the last has been read."""
        ring = self.settings.ring_radius
        bed_speed = math.degrees(self.speed / ring)
        bed_accel = math.degrees(self.accel / ring)
        gcode = self.printer.lookup_object("gcode")
        saved_accel = toolhead.max_accel
        windows = []
        self.samples = []
        with kin.joint_space_solvers():
            gcode.run_script_from_command("SET_VELOCITY_LIMIT ACCEL=%.6f" % (bed_accel,))
            try:
                kin.enter_joint_space()
                pos = toolhead.get_position()
                for i, arm in enumerate(arms):
                    start, end = -overlap_deg, 360. + overlap_deg
                    if i % 2:
                        start, end = end, start
                    # To the pass's start: the arm at its speed, the bed (first pass only) at the scan's.
                    speed = kin.max_velocity if pos[1] == start else bed_speed
                    pos[0], pos[1] = arm, start
                    toolhead.move(list(pos), speed)
                    t0 = toolhead.get_last_move_time()
                    pos[1] = end
                    toolhead.move(list(pos), bed_speed)
                    windows.append((t0, toolhead.get_last_move_time()))
                toolhead.wait_moves()
                # The last reports arrive a little after the motion ends.
                reactor = self.printer.get_reactor()
                reactor.pause(reactor.monotonic() + 0.25)
            finally:
                gcode.run_script_from_command("SET_VELOCITY_LIMIT ACCEL=%.6f" % (saved_accel,))
        kin.leave_joint_space()
        return windows

    def _config_dir(self):
        config_file = self.printer.get_start_args().get("config_file", "printer.cfg")
        return os.path.dirname(os.path.abspath(config_file))

    def _write(self, name, text):
        path = os.path.join(self._config_dir(), name)
        with open(path + ".tmp", "w") as f:
            f.write(text)
        os.replace(path + ".tmp", path)
        return path

    def _write_samples(self, rows):
        if rows:
            self._write("jointspace-centre-samples.csv", "pass,arm_mm,bed_deg,adc\n" + "".join(
                "%d,%.6f,%.6f,%.6f\n" % (i, arm, math.degrees(bed), value) for i, arm, bed, value in rows))

    def _fit(self, gcmd, rows, pass_count):
        ffi = self.ffi
        samples = ffi.new("double[]", 4 * max(1, len(rows)))
        for k, row in enumerate(rows):
            samples[4 * k:4 * k + 4] = row
        result = ffi.new("double[4]")
        csv = ffi.new("char[]", CSV_LEN)
        report = ffi.new("char[]", REPORT_LEN)
        rc = self.lib.jointspace_scan_centre(self.settings, samples, len(rows), result, csv, CSV_LEN,
                                             report, REPORT_LEN)
        message = ffi.string(report).decode()
        if rc != 0:
            raise gcmd.error("jointspace: centre scan refused, nothing stored (%d passes, %d readings): %s"
                             % (pass_count, len(rows), message or "result too large"))
        path = self._write("jointspace-centre-scan.csv", ffi.string(csv).decode())
        self.last_result = {"arm_zero_offset": result[0], "arm_lateral_offset": result[1],
                            "sigma_arm_zero_offset": result[2], "sigma_arm_lateral_offset": result[3]}
        configfile = self.printer.lookup_object("configfile")
        configfile.set("printer", "arm_zero_offset", "%.4f" % (result[0],))
        configfile.set("printer", "arm_lateral_offset", "%.4f" % (result[1],))
        gcmd.respond_info(
            "jointspace: rotation centre found: %s\ndetections written to %s (jointspace calibrate centre "
            "--scan reads it)\nRun SAVE_CONFIG to store arm_zero_offset and arm_lateral_offset and restart."
            % (message, path))
