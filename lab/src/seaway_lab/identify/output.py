"""What a fit writes: the vessel file (TOML, loadable by ``load_vessel``) and the held-out plot."""

from __future__ import annotations

import math
from pathlib import Path

from seaway.vessel.model import VesselParams

from seaway_lab.identify.fit import FitResult

_UNITS = {"m11_kg": "kg", "m22_kg": "kg", "m33_kgm2": "kg m^2", "xu_kgps": "kg/s",
          "yv_kgps": "kg/s", "nr_kgm2ps": "kg m^2/s", "friction_n": "N", "static_friction_n": "N"}


def _f(x: float) -> str:
    return f"{x:.6g}"


def vessel_toml(result: FitResult, base: VesselParams, name: str, source: str) -> str:
    """The fitted vessel as a vessel file: the fitted parameters, the arm used, the dead zone and
    lag, and what the motion cannot give (alpha, thrust bounds) from ``base``; the fit in comments."""
    r = result
    lines = [
        f"# Identified by `seaway identify fit` from {source}",
        f"# ({r.samples} weighted residuals fitted on t < {r.split_s:.1f} s of the run, "
        f"{r.iterations} Levenberg-Marquardt iterations; output error, see seaway_lab.identify.fit).",
        "# Each fitted value: estimate, its standard error (1 sigma, from the regression, assuming white",
        "# residuals), and the equation-error value the fit started from.",
        f"name = \"{name}\"",
        f"description = \"identified from {Path(source).name}\"",
    ]
    for p, e in (*r.params.items(), *r.friction.items()):
        start = f", start {_f(r.start[p])}" if p in r.start else ""
        lines.append(f"{p} = {_f(e.value)}  # +- {e.std:.3g} {_UNITS[p]} ({100 * e.rel_std:.2f} %)"
                     + start)
    if r.friction:
        lines.append(f"friction_speed_mps = {_f(r.friction_speed_mps)}  # not fitted: the fit's least, "
                     "or what the control period integrates (seaway_lab.identify.parameters) if more")
    rat = r.ratios
    lines += [
        f"arm_m = {_f(r.arm_m)}  # fixed (the vessel drawing), not fitted: the yaw data give "
        f"m33/l = {rat['m33_over_arm_kgm']:.4g} kg m and Nr/l = {rat['nr_over_arm_kgmps']:.4g} kg m/s",
        f"alpha_w_per_n2 = {_f(base.alpha_w_per_n2)}  # from {base.name}: power is not in the motion",
        f"thrust_max_n = {_f(base.thrust_max_n)}  # from {base.name}",
    ]
    if base.reverse_thrust_max_n is not None:
        lines.append(f"reverse_thrust_max_n = {_f(base.reverse_thrust_max_n)}  # from {base.name}")
    dz_note = ("profiled over the slow ramp (equation error)" if r.dead_zone_profile
               else "as given, not fitted")
    lines += [f"dead_zone_n = {_f(r.dead_zone_n)}  # {dz_note}",
              f"thruster_time_constant_s = {_f(r.lag_s)}",
              f"# water current fitted alongside: north {r.current_ne_mps[0]:+.3f} m/s, "
              f"east {r.current_ne_mps[1]:+.3f} m/s",
              "# residual RMS, fitted part:   " + _rms(r.rms_fit),
              "# residual RMS, held-out part: " + _rms(r.rms_holdout)]
    lines += [f"# note: {n}" for n in r.notes]
    if base.battery is not None:  # not in the motion either: the base vessel's pack, as given
        lines += ["", f"# the propulsion battery, from {base.name}", "[battery]"]
        lines += [f"{k} = {_f(v)}" for k, v in base.battery.model_dump(exclude_none=True).items()]
    return "\n".join(lines) + "\n"


def _rms(d: dict[str, float]) -> str:
    return (f"u {d['u_mps']:.4f} m/s, v {d['v_mps']:.4f} m/s, r {d['r_radps']:.4f} rad/s"
            if not any(math.isnan(x) for x in d.values()) else "none (no samples)")


def plot(result: FitResult, path: Path, title: str = "") -> Path:
    """Measured against predicted u, v, r over the held-out part of the run (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = result.prediction
    g = p.t_s >= result.split_s
    a = p.r_t_s >= result.split_s
    if not g.any():  # nothing held out: show the whole run
        g[:] = True
        a[:] = True
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    for ax, t, meas, pred, label in (
            (axes[0], p.t_s[g], p.u_meas[g], p.u_pred[g], "u [m/s]"),
            (axes[1], p.t_s[g], p.v_meas[g], p.v_pred[g], "v [m/s]"),
            (axes[2], p.r_t_s[a], p.r_meas[a], p.r_pred[a], "r [rad/s]")):
        ax.plot(t, meas, ".", ms=2, color="0.5", label="measured")
        ax.plot(t, pred, "-", lw=1.2, color="C0", label="predicted (identified model)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[2].set_xlabel("time from the first command [s]")
    h = result.rms_holdout
    fig.suptitle((title + "\n" if title else "") + "held out of the fit: "
                 + (f"RMS u {h['u_mps']:.3f} m/s, v {h['v_mps']:.3f} m/s, r {h['r_radps']:.4f} rad/s"
                    if not math.isnan(h["u_mps"]) else "nothing (whole run shown)"), fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
