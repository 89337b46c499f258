"""Flights: what the firmware is judged by (docs/flights.md).

* :mod:`.record`: :class:`FlightRecord`, the one in-memory form of a flight (real log or simulation), in SI units.
* readers (real logs and a generic CSV), sensor models and resampling turn a record into firmware inputs;
* simulators (a fast 1-DOF model, RocketPy 6-DOF as an optional extra) make records with truth;
* evaluation runs firmware methods over records and builds the apogee table.
"""

from firmware_model.flights.record import FlightRecord, Truth

__all__ = ["FlightRecord", "Truth"]
