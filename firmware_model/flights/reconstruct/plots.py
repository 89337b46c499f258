"""PNG figures of a reconstruction in Chari's style (matplotlib, lazily, Agg): estimate error with +-2 sigma bounds
against truth, the trajectory, the tilt. Each function returns PNG bytes; callers write them atomically."""

from __future__ import annotations

from typing import Any

import numpy as np

from firmware_model.flights.plot import _png, _pyplot

AXES = ("east", "north", "up")
GROUPS = (("pos", "position error (m)"), ("vel", "velocity error (m/s)"), ("att", "attitude error (deg)"))


def plot_errors(t: np.ndarray, f: dict[str, np.ndarray], s: dict[str, np.ndarray] | None, title: str,
                t_apogee: float | None = None) -> bytes:
    """3 x 3 panels: position, velocity, attitude error per site axis; filter error and +-2 sigma (thin, grey),
    smoother error and +-2 sigma (blue)."""
    plt = _pyplot()
    fig, axs = plt.subplots(3, 3, figsize=(13, 8.5), sharex=True)
    for row, (g, label) in enumerate(GROUPS):
        scale = np.degrees(1.0) if g == "att" else 1.0
        for col in range(3):
            ax = axs[row, col]
            ax.plot(t, f[g][:, col] * scale, color="0.45", lw=0.7, label="filter error")
            ax.plot(t, 2 * f[f"sig_{g}"][:, col] * scale, color="0.45", lw=0.6, ls="--", label="filter +-2 sigma")
            ax.plot(t, -2 * f[f"sig_{g}"][:, col] * scale, color="0.45", lw=0.6, ls="--")
            if s is not None:
                ax.plot(t, s[g][:, col] * scale, color="tab:blue", lw=0.9, label="smoother error")
                ax.plot(t, 2 * s[f"sig_{g}"][:, col] * scale, color="tab:blue", lw=0.7, ls="--",
                        label="smoother +-2 sigma")
                ax.plot(t, -2 * s[f"sig_{g}"][:, col] * scale, color="tab:blue", lw=0.7, ls="--")
            ax.axhline(0.0, color="k", lw=0.4)
            if t_apogee is not None:
                ax.axvline(t_apogee, color="tab:red", lw=0.5)
            lim = np.nanpercentile(np.abs(2 * f[f"sig_{g}"][:, col] * scale), 95) * 1.6
            if np.isfinite(lim) and lim > 0:
                ax.set_ylim(-lim, lim)
            if row == 0:
                ax.set_title(AXES[col] if g != "att" else AXES[col])
            if col == 0:
                ax.set_ylabel(label)
            if row == 2:
                ax.set_xlabel("time from ignition (s)")
    axs[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle(title)
    fig.tight_layout()
    return _png(fig)


def plot_trajectory(r: np.ndarray, r_truth: np.ndarray | None, title: str, horizontal: bool = True) -> bytes:
    """Ground track (east/north) and altitude against horizontal range; truth dashed when known."""
    plt = _pyplot()
    fig, axs = plt.subplots(1, 2, figsize=(11, 4.5))
    if horizontal:
        axs[0].plot(r[:, 0], r[:, 1], label="reconstruction")
        if r_truth is not None:
            axs[0].plot(r_truth[:, 0], r_truth[:, 1], "k--", lw=0.8, label="truth")
        axs[0].set_xlabel("east (m)")
        axs[0].set_ylabel("north (m)")
        axs[0].set_aspect("equal", adjustable="datalim")
        axs[0].legend(fontsize=8)
        rng = np.hypot(r[:, 0], r[:, 1])
        axs[1].plot(rng, r[:, 2])
        if r_truth is not None:
            axs[1].plot(np.hypot(r_truth[:, 0], r_truth[:, 1]), r_truth[:, 2], "k--", lw=0.8)
        axs[1].set_xlabel("horizontal distance from the pad (m)")
    else:
        axs[0].text(0.5, 0.5, "vertical channel only:\nno horizontal reconstruction", ha="center", va="center",
                    transform=axs[0].transAxes)
        axs[0].set_axis_off()
        axs[1].plot(np.arange(r.shape[0]), r[:, 2])
        axs[1].set_xlabel("sample")
    axs[1].set_ylabel("altitude above the pad (m)")
    fig.suptitle(title)
    fig.tight_layout()
    return _png(fig)


def plot_states(t: np.ndarray, z: np.ndarray, sz: np.ndarray, vz: np.ndarray, svz: np.ndarray,
                tilt: np.ndarray | None, title: str, marks: dict[str, float] | None = None,
                tilt_truth: np.ndarray | None = None, extra: dict[str, Any] | None = None) -> bytes:
    """Altitude and vertical velocity with +-2 sigma bands, and tilt (deg), against time; vertical lines at
    ``marks`` (label -> time)."""
    plt = _pyplot()
    n = 3 if tilt is not None else 2
    fig, axs = plt.subplots(n, 1, figsize=(10, 2.8 * n), sharex=True)
    axs[0].plot(t, z, lw=0.9)
    axs[0].fill_between(t, z - 2 * sz, z + 2 * sz, alpha=0.3, label="+-2 sigma")
    if extra and "baro_altitude" in extra:
        axs[0].plot(extra["baro_t"], extra["baro_altitude"], ".", ms=1, color="0.5", label="barometer")
    axs[0].set_ylabel("altitude (m)")
    axs[1].plot(t, vz, lw=0.9)
    axs[1].fill_between(t, vz - 2 * svz, vz + 2 * svz, alpha=0.3)
    axs[1].axhline(0.0, color="k", lw=0.4)
    axs[1].set_ylabel("vertical velocity (m/s)")
    if tilt is not None:
        axs[2].plot(t, tilt, lw=0.9, label="reconstruction")
        if tilt_truth is not None:
            axs[2].plot(t, tilt_truth, "k--", lw=0.8, label="truth")
        if extra and "tilt_log" in extra:
            axs[2].plot(extra["tilt_log_t"], extra["tilt_log"], lw=0.8, label="flight computer's own tilt")
        axs[2].set_ylabel("tilt from vertical (deg)")
        axs[2].legend(fontsize=8)
    for ax in axs:
        for label, tm in (marks or {}).items():
            ax.axvline(tm, lw=0.6, ls=":", color="tab:red")
    if marks:
        axs[0].text(0.01, 0.95, "; ".join(f"{k} {v:.3f} s" for k, v in marks.items()), transform=axs[0].transAxes,
                    va="top", fontsize=8)
    axs[0].legend(fontsize=8, loc="lower right")
    axs[-1].set_xlabel("time (s)")
    fig.suptitle(title)
    fig.tight_layout()
    return _png(fig)
