G28
G90
hello world
