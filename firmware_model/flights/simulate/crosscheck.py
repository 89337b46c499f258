"""Cross-check of the 1-DOF model against RocketPy on vertical no-wind flights of the same rocket (docs/flights-sim.md).

``python -m firmware_model.flights.simulate.crosscheck [PNG]`` simulates the cross-check rockets with both simulators,
prints apogee altitude and time and burnout velocity side by side, and (with a path) writes the figure: altitude
and vertical velocity against time, both simulators, plus their differences.
"""

from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import dataclass

import numpy as np

from firmware_model.flights.simulate.motors import load_motor
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.simulate.rocketpy_sim import simulate_rocketpy
from firmware_model.flights.simulate.sim1dof import Launch, Rocket, simulate_1dof

#: The rockets cross-checked (vertical, no wind, same mass, diameter, drag curve and motor in both simulators).
CROSS_CHECK_ROCKETS: dict[str, Rocket] = {
    "K828FJ subsonic": Rocket("xc-k828", dry_mass_kg=10.0, diameter_m=0.08, motor=load_motor("K828FJ")),
    "M1670 transonic": Rocket("xc-m1670", dry_mass_kg=12.0, diameter_m=0.127, motor=load_motor("M1670")),
}
CROSS_CHECK_LAUNCH = Launch(record_hz=1000.0, descent_s=3.0)


@dataclass(frozen=True)
class Comparison:
    """The two simulators' figures for one rocket."""

    name: str
    apogee_m: tuple[float, float]          # (1-DOF, RocketPy), geopotential AGL
    apogee_time_s: tuple[float, float]
    burnout_velocity_mps: tuple[float, float]
    max_mach: tuple[float, float]
    one: FlightRecord
    rpy: FlightRecord

    @property
    def apogee_rel(self) -> float:
        return (self.apogee_m[1] - self.apogee_m[0]) / self.apogee_m[0]

    @property
    def apogee_dt(self) -> float:
        return self.apogee_time_s[1] - self.apogee_time_s[0]

    @property
    def burnout_rel(self) -> float:
        return (self.burnout_velocity_mps[1] - self.burnout_velocity_mps[0]) / self.burnout_velocity_mps[0]

    def line(self) -> str:
        return (f"{self.name}: apogee {self.apogee_m[0]:.2f} m (1-DOF) vs {self.apogee_m[1]:.2f} m (RocketPy), "
                f"{100 * self.apogee_rel:+.3f} %; apogee time {self.apogee_time_s[0]:.3f} vs "
                f"{self.apogee_time_s[1]:.3f} s ({1000 * self.apogee_dt:+.1f} ms); burnout velocity "
                f"{self.burnout_velocity_mps[0]:.2f} vs {self.burnout_velocity_mps[1]:.2f} m/s "
                f"({100 * self.burnout_rel:+.3f} %); peak Mach {self.max_mach[0]:.3f} vs {self.max_mach[1]:.3f}")


def compare(name: str, rocket: Rocket, launch: Launch = CROSS_CHECK_LAUNCH) -> Comparison:
    """Simulate ``rocket`` vertically without wind with both simulators."""

    one = simulate_1dof(rocket, launch)[0]
    rpy = simulate_rocketpy(rocket, launch, inclination_deg=90.0)
    s1, s2 = one.provenance["summary"], rpy.provenance["summary"]
    return Comparison(name=name,
                      apogee_m=(one.truth.apogee_altitude_m, rpy.truth.apogee_altitude_m),
                      apogee_time_s=(one.truth.apogee_time_s, rpy.truth.apogee_time_s),
                      burnout_velocity_mps=(s1["burnout_velocity_mps"], s2["burnout_velocity_mps"]),
                      max_mach=(s1["max_mach"], s2["max_mach"]), one=one, rpy=rpy)


def plot(comparisons: list[Comparison], path: str) -> None:
    """Altitude and velocity vs time for both simulators (top), differences RocketPy - 1-DOF (bottom)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(comparisons), figsize=(6.5 * len(comparisons), 7.5), squeeze=False,
                             gridspec_kw={"height_ratios": [2.2, 1]})
    for col, c in enumerate(comparisons):
        ax = axes[0, col]
        ax2 = ax.twinx()
        t1, t2 = c.one.time_s, c.rpy.time_s
        ax.plot(t1, c.one.truth.altitude_m, color="C0", lw=2.2, label="altitude, 1-DOF")
        ax.plot(t2, c.rpy.truth.altitude_m, color="C1", lw=1.0, ls="--", label="altitude, RocketPy")
        ax2.plot(t1, c.one.truth.velocity_mps, color="C2", lw=2.2, label="velocity, 1-DOF")
        ax2.plot(t2, c.rpy.truth.velocity_mps, color="C3", lw=1.0, ls="--", label="velocity, RocketPy")
        ax.set_title(f"{c.name}: apogee {c.apogee_m[0]:.0f} m, {100 * c.apogee_rel:+.2f} %; "
                     f"{1000 * c.apogee_dt:+.0f} ms", fontsize=9)
        ax.set_xlabel("time from ignition (s)")
        ax.set_ylabel("altitude AGL (m)")
        ax2.set_ylabel("vertical velocity (m/s)")
        ax.grid(alpha=0.3)
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="center right")
        bx = axes[1, col]
        bx2 = bx.twinx()
        n = min(c.one.n, c.rpy.n)
        assert np.array_equal(t1[:n], t2[:n])
        bx.plot(t1[:n], c.rpy.truth.altitude_m[:n] - c.one.truth.altitude_m[:n], color="C0",
                label="altitude RocketPy - 1-DOF (m)")
        bx2.plot(t1[:n], c.rpy.truth.velocity_mps[:n] - c.one.truth.velocity_mps[:n], color="C2",
                 label="velocity RocketPy - 1-DOF (m/s)")
        bx.set_xlabel("time from ignition (s)")
        bx.set_ylabel("altitude diff (m)")
        bx2.set_ylabel("velocity diff (m/s)")
        bx.grid(alpha=0.3)
        h1, l1 = bx.get_legend_handles_labels()
        h2, l2 = bx2.get_legend_handles_labels()
        bx.legend(h1 + h2, l1 + l2, fontsize=8, loc="lower left")
    fig.tight_layout()
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=d, suffix=".png.tmp")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110, format="png")
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    comps = [compare(name, r) for name, r in CROSS_CHECK_ROCKETS.items()]
    for c in comps:
        print(c.line())
    if argv:
        plot(comps, argv[0])
        print(f"wrote {argv[0]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
