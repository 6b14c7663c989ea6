G28
G90
G1 X10 (move right
G1 Y10
