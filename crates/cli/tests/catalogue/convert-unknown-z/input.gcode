; no homing pose for Z in the config, and the file moves before it sets Z
M83
G1 X10 Y5 E1 F600
G1 Z0.3
