# Cura post-processing script: rewrites the G-code's print time (;TIME:, ;TIME_ELAPSED:, M73) with the time
# jointspace plans for the printer (`jointspace post-process`), so Moonraker and Mainsail show the true time.
#
# Install: copy this file into Cura's scripts folder (Help > Show Configuration Folder, then `scripts/`), restart
# Cura, and add "jointspace print times" under Extensions > Post Processing > Modify G-Code. Set the path of the
# `jointspace` binary and of the printer's printer.cfg. MIT or Apache-2.0, as jointspace.
#
# On any error (no binary, a config error, a move the machine refuses) the G-code is left as Cura wrote it and the
# reason goes to Cura's log.

import os
import subprocess
import tempfile

from UM.Logger import Logger

from ..Script import Script


class JointspaceTimes(Script):
    def getSettingDataString(self):
        return """{
            "name": "jointspace print times",
            "key": "JointspaceTimes",
            "metadata": {},
            "version": 2,
            "settings": {
                "jointspace": {
                    "label": "jointspace binary",
                    "description": "Path of the jointspace program.",
                    "type": "str",
                    "default_value": "jointspace"
                },
                "config": {
                    "label": "printer.cfg",
                    "description": "The printer's Klipper configuration (with [jointspace] for polar and SCARA machines).",
                    "type": "str",
                    "default_value": ""
                }
            }
        }"""

    def execute(self, data):
        binary = self.getSettingValueByKey("jointspace")
        config = self.getSettingValueByKey("config")
        # Cura hands the G-code over in pieces (one per layer); the rewrite keeps every line, so the pieces are cut
        # again at the same line counts.
        counts = [piece.count("\n") for piece in data]
        fd, path = tempfile.mkstemp(suffix=".gcode")
        try:
            with os.fdopen(fd, "w", newline="") as f:
                f.write("".join(data))
            result = subprocess.run([binary, "post-process", "-c", config, path],
                                    capture_output=True, text=True)
            if result.returncode != 0:
                Logger.log("w", "jointspace post-process failed: %s", result.stderr)
                return data
            with open(path, newline="") as f:
                lines = f.read().splitlines(keepends=True)
        except OSError as e:
            Logger.log("w", "jointspace post-process could not run: %s", e)
            return data
        finally:
            if os.path.exists(path):
                os.remove(path)
        pieces, start = [], 0
        for count in counts:
            pieces.append("".join(lines[start:start + count]))
            start += count
        if start < len(lines):
            pieces[-1] += "".join(lines[start:])
        return pieces
