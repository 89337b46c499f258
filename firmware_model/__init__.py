"""Bit-exact fixed-point models, firmware sources, gain design, flight inputs and golden vectors for rocket apogee
filters."""
