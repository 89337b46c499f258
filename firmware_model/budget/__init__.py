"""budget: cycles, RAM, ROM and load per build, on the 68000 and on microcontrollers. Imports everything below
cli."""
