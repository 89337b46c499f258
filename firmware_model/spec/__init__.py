"""spec: what a firmware build is: build configuration, gain design, quantisation and fixed point, the standard
atmosphere, the altitude table, tunings and the design report. Imports runtime only."""
