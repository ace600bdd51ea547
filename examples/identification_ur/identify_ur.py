"""Identification of a UR-type arm with joint friction from simulated measurements, and the
identified feedforward in a 1 kHz C control loop (issue 38, item 5).

1. **Excitation.**  A periodic Fourier excitation (T = 10 s, 3 harmonics per joint) minimising
   the conditioning of the stacked base regressor under the URDF's position and velocity limits
   and an acceleration limit (:func:`casmbd.ocp.excitation.excitation_for`).
2. **Measurements.**  The "real" arm is examples/ur5_arm.urdf plus viscous and Coulomb friction
   on every joint (:data:`TRUE_FRICTION`, casmbd's regularised law Q = −F_v q̇ −
   F_c tanh(q̇ / 10⁻³)).  It follows the excitation for :data:`PERIODS` periods; the joint
   torques are its inverse dynamics (:func:`casmbd.compile`, Newton–Euler with friction),
   sampled at :data:`RATE` Hz.  Seeded Gaussian noise is added to q (σ = :data:`NOISE_Q`: a
   motor-side encoder seen through the gear) and τ (:data:`NOISE_TAU`, per joint: torques
   estimated from motor currents); only q and τ are written to ``MEASURED.csv`` (columns
   ``t, q.<coordinate>, tau.<coordinate>``).
3. **Identification.**  ``casmbd identify examples/ur5_arm.urdf --data MEASURED.csv --friction
   viscous,coulomb --cutoff 20 --decimate 10 --out ur5_identified.urdf``: q and τ are
   low-passed alike (zero-phase Butterworth, 20 Hz), q is differentiated twice, samples near
   velocity reversals are left out (the regularised Coulomb law is steep there), and every
   10th sample is kept (50 Hz: the residuals of neighbouring samples are then nearly
   uncorrelated, which the reported σ assumes); weighted least squares of the base parameters
   with their standard deviations, then physically consistent standard parameters written
   into the identified URDF.  The identified base parameters are compared with the truth
   π_b = K π_true, in units of the reported σ.
4. **Validation.**  A different (random, feasible) Fourier trajectory: the torques predicted by
   the identified base parameters, Y_b(q, q̇, q̈) π̂_b, against the true ones.
5. **C feedforward.**  The identified model (physically consistent standard parameters and
   friction) exported as standalone C (``casmbd export``), and ``control_loop.c``: a 1 kHz
   computed-torque loop over the validation trajectory that calls the exported inverse dynamics
   and prints the largest difference to the Python API's torques.

Run: ``python examples/identification_ur/identify_ur.py [--out DIR] [--quick] [--figures]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import pathlib
import shutil
import subprocess
import tempfile

import numpy as np

import casmbd
from casmbd import cli
from casmbd.analysis.identification.parameters import parameter_vector, standard_parameters
from casmbd.io.scene import load_scene
from casmbd.io.urdf import load_urdf
from casmbd.ocp.excitation import (
    FourierTrajectory,
    excitation_for,
    random_feasible,
)

HERE = pathlib.Path(__file__).resolve().parent
URDF = HERE.parent / "ur5_arm.urdf"
#: viscous F_v [N m s/rad] and Coulomb F_c [N m] of the "real" arm, per joint
TRUE_FRICTION = {"shoulder_pan_joint": (4.0, 6.0), "shoulder_lift_joint": (4.5, 7.0),
                 "elbow_joint": (3.0, 4.0), "wrist_1_joint": (0.8, 1.2),
                 "wrist_2_joint": (0.7, 1.0), "wrist_3_joint": (0.5, 0.8)}
FRICTION = ("viscous", "coulomb")
PERIOD, HARMONICS, ACCELERATION = 10.0, 3, 3.0   # s, -, rad/s²
PERIODS, RATE = 2, 500.0                         # measured periods, sampling rate [Hz]
CUTOFF, DECIMATE = 20.0, 10                      # low-pass cut-off [Hz], decimation
NOISE_Q = 1e-5                                   # rad
NOISE_TAU = np.array([0.5, 0.5, 0.3, 0.05, 0.05, 0.05])  # N m
LOOP_RATE = 1000.0                               # control loop [Hz]
SEED = 38


def true_arm():
    """The "real" arm: the URDF's inertias plus :data:`TRUE_FRICTION` on every joint."""
    mech = load_urdf(URDF)
    for joint, (viscous, coulomb) in TRUE_FRICTION.items():
        mech.add("joint_friction", f"{joint}_friction", joint, damping=viscous,
                 friction=coulomb)
    return mech


def true_parameters(base, mech_true) -> np.ndarray:
    """π of the identification model (names ``link.m`` …, ``joint.viscous``, ``joint.coulomb``)
    at the true values."""
    truth = standard_parameters(mech_true, FRICTION)
    values = dict(zip(truth.names, truth.values, strict=True))
    return parameter_vector(base.standard, {k: values[k] for k in base.standard.names})


def design(quick: bool):
    """Step 1: the optimised excitation on the identification model (no friction elements:
    the friction laws are parameters of the regressor)."""
    mech = load_urdf(URDF)
    return excitation_for(mech, period=PERIOD, acceleration=ACCELERATION,
                          friction=FRICTION, harmonics=HARMONICS, samples=40,
                          max_iter=40 if quick else 80, seed=SEED)


def measure(traj: FourierTrajectory, coordinates: list[str], out: pathlib.Path,
            rng: np.random.Generator):
    """Step 2: sample the true arm along ``traj`` and write MEASURED.csv (q and τ, noisy)."""
    arm = casmbd.compile(true_arm())
    t = np.arange(int(PERIODS * PERIOD * RATE)) / RATE
    q, v, a = traj.evaluate(t)
    tau = arm.inverse_dynamics_batch(q, v, a)
    q_m = q + NOISE_Q * rng.standard_normal(q.shape)
    tau_m = tau + NOISE_TAU * rng.standard_normal(tau.shape)
    header = ",".join(["t"] + [f"q.{c}" for c in coordinates] + [f"tau.{c}" for c in coordinates])
    path = out / "MEASURED.csv"
    np.savetxt(path, np.column_stack([t, q_m, tau_m]), delimiter=",", header=header,
               comments="", fmt="%.12g")
    return path, (t, q, v, a, tau)


def casmbd_cli(*argv: str) -> dict:
    """Run ``casmbd ARGV --json`` in this process (as the command line does) and return its
    JSON object."""
    buf, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
        status = cli.main([*argv, "--json"])
    if status != 0:
        raise RuntimeError(f"casmbd {argv[0]} failed ({status}): {err.getvalue().strip()}")
    return json.loads(buf.getvalue())


def identify(path: pathlib.Path, out: pathlib.Path) -> dict:
    """Step 3: ``casmbd identify`` (its JSON summary); it also writes the identified URDF."""
    argv = ["identify", str(URDF), "--data", str(path), "--friction", ",".join(FRICTION),
            "--cutoff", str(CUTOFF), "--decimate", str(DECIMATE), "--out",
            str(out / "ur5_identified.urdf")]
    summary = casmbd_cli(*argv)
    summary["how"] = " ".join(["casmbd", *argv])
    return summary


def run(out: str | os.PathLike | None = None, quick: bool = False,
        figures: str | os.PathLike | None = None, control_loop: bool = True) -> dict:
    """The whole example; returns the numbers it prints."""
    out = pathlib.Path(out or tempfile.mkdtemp(prefix="identify_ur_"))
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(SEED)
    # 1. excitation
    excitation, base = design(quick)
    traj = excitation.trajectory
    coords = casmbd.compile(load_urdf(URDF), mode="vm").coordinate_names
    # 2. measurements
    path, clean = measure(traj, coords, out, rng)
    # 3. identification
    summary = identify(path, out)
    names = [p["name"] for p in summary["base_parameters"]]
    if names != list(base.names):
        raise RuntimeError("the identified base parameters are not the designed ones")
    estimate = np.array([p["value"] for p in summary["base_parameters"]])
    std = np.array([p["std"] for p in summary["base_parameters"]])
    truth = base.K @ true_parameters(base, true_arm())
    z = (estimate - truth) / std
    # 4. validation on another trajectory
    lim = design_limits()
    other = random_feasible(6, HARMONICS, PERIOD, seed=SEED + 1, **lim)
    t_val = np.arange(int(PERIOD * LOOP_RATE)) / LOOP_RATE
    qv, vv, av = other.evaluate(t_val)
    tau_true = casmbd.compile(true_arm()).inverse_dynamics_batch(qv, vv, av)
    tau_measured = tau_true + NOISE_TAU * rng.standard_normal(tau_true.shape)
    yb = np.array(base.symbolic.map(len(t_val))(qv.T, vv.T, av.T)).reshape(6, len(t_val), -1)
    tau_pred = np.einsum("jkp,p->kj", yb, estimate)
    err = tau_pred - tau_true
    rms_true = np.sqrt(np.mean(tau_true ** 2, axis=0))
    result = {
        "out": str(out), "how": summary["how"],
        "condition_random": excitation.initial_condition, "condition": excitation.condition,
        "identification_condition": summary["condition_number"],
        "base_names": names, "estimate": estimate, "std": std, "truth": truth, "z": z,
        "max_abs_z": float(np.max(np.abs(z))),
        "validation_rms_error": np.sqrt(np.mean(err ** 2, axis=0)),
        "validation_rms_torque": rms_true,
        "validation_relative": float(np.sqrt(np.mean(err ** 2)) / np.sqrt(np.mean(tau_true ** 2))),
        "excitation": traj, "validation": other, "t_val": t_val, "tau_true": tau_true,
        "tau_measured": tau_measured, "tau_pred": tau_pred, "clean": clean, "summary": summary,
    }
    if control_loop:
        result.update(c_feedforward(out, other, t_val))
        if "tau_consistent" in result:
            gap = result["tau_consistent"] - tau_true
            result["validation_consistent_relative"] = float(
                np.sqrt(np.mean(gap ** 2)) / np.sqrt(np.mean(tau_true ** 2)))
    if figures:
        plot(result, pathlib.Path(figures))
    return result


def design_limits() -> dict:
    """The limits of the design (URDF position and velocity, the acceleration limit), for the
    random validation trajectory."""
    from casmbd.ocp.excitation import joint_limits
    lim = joint_limits(load_urdf(URDF))
    return {"lower": lim["lower"], "upper": lim["upper"], "velocity": lim["velocity"],
            "acceleration": ACCELERATION}


def c_feedforward(out: pathlib.Path, traj: FourierTrajectory, t: np.ndarray) -> dict:
    """Step 5: export the identified model's inverse dynamics as C (``casmbd export``),
    compile control_loop.c with it and run the 1 kHz loop over the validation trajectory
    ``traj`` at the instants ``t``, against the Python API's torques."""
    urdf = out / "ur5_identified.urdf"
    if not urdf.exists():
        return {"c_loop": "skipped: no identified URDF was written"}
    scene = out / "identified.toml"  # the URDF with its <dynamics> applied as joint friction
    scene.write_text('[scene]\nname = "ur5_identified"\nurdf = "ur5_identified.urdf"\n'
                     "damping = true\nfriction = true\n")
    cdir = out / "c"
    if cdir.exists():
        shutil.rmtree(cdir)
    casmbd_cli("export", str(scene), "--c", str(cdir), "--functions", "inverse_dynamics",
               "--prefix", "ur5")
    q, v, a = traj.evaluate(t)
    tau_py = casmbd.compile(load_scene(scene)).inverse_dynamics_batch(q, v, a)
    coefficients = out / "trajectory.txt"
    with open(coefficients, "w") as f:
        f.write(f"{traj.period!r} {traj.a.shape[0]} {traj.harmonics}\n")
        for block in (traj.q0, traj.a.ravel(), traj.b.ravel()):
            f.write(" ".join(repr(float(x)) for x in block) + "\n")
    reference = out / "reference.csv"
    np.savetxt(reference, tau_py, delimiter=" ", fmt="%.17g")
    exe = out / "control_loop"
    cc = shutil.which("cc")
    if cc is None:
        return {"c_loop": "skipped: no C compiler 'cc' on PATH"}
    build = subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic",
                            f"-I{cdir}", str(HERE / "control_loop.c"), str(cdir / "ur5.c"),
                            str(cdir / "ur5_model.c"), "-o", str(exe), "-lm"],
                           capture_output=True, text=True, check=False)
    if build.returncode != 0:
        raise RuntimeError(f"cc failed: {build.stderr.strip()[-800:]}")
    ran = subprocess.run([str(exe), str(coefficients), str(reference)], capture_output=True,
                         text=True, check=False)
    if ran.returncode != 0:
        raise RuntimeError(f"control_loop failed ({ran.returncode}): {ran.stderr}")
    found = dict(item.split("=", 1) for item in ran.stdout.split() if "=" in item)
    return {"c_loop": "ran", "c_steps": int(found["steps"]),
            "c_max_torque_difference": float(found["max_torque_difference"]),
            "c_max_torque": float(found["max_torque"]), "c_stdout": ran.stdout.strip(),
            "tau_consistent": tau_py,
            "c_build_warnings": build.stderr.strip()}


def plot(result: dict, figures: pathlib.Path) -> None:
    """The excitation trajectory, and measured vs predicted torques on the validation run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    figures.mkdir(parents=True, exist_ok=True)
    traj = result["excitation"]
    t = np.linspace(0.0, traj.period, 1001)
    q, v, _ = traj.evaluate(t)
    fig, ax = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    labels = ["pan", "lift", "elbow", "wrist 1", "wrist 2", "wrist 3"]
    for j in range(q.shape[1]):
        ax[0].plot(t, q[:, j], label=labels[j])
        ax[1].plot(t, v[:, j])
    ax[0].set_ylabel("q [rad]")
    ax[1].set_ylabel("q̇ [rad/s]")
    ax[1].set_xlabel("t [s]")
    ax[0].legend(ncol=6, fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.08))
    fig.suptitle(f"Optimised excitation (T = {traj.period:g} s, {traj.harmonics} harmonics): "
                    f"κ = {result['condition']:.0f} (random feasible: "
                 f"{result['condition_random']:.0f})", fontsize=10)
    fig.tight_layout()
    fig.savefig(figures / "identification_excitation.png", dpi=110)
    plt.close(fig)
    tv, tau_true, tau_pred = result["t_val"], result["tau_true"], result["tau_pred"]
    fig, ax = plt.subplots(3, 2, figsize=(9, 6.5), sharex=True)
    for j in range(6):
        axis = ax[j % 3, j // 3]
        axis.plot(tv, result["tau_measured"][:, j], color="0.7", lw=0.6, label="measured")
        axis.plot(tv, tau_true[:, j], "k-", lw=0.8, label="true")
        axis.plot(tv, tau_pred[:, j], "r--", lw=1.0, label="identified")
        axis.set_ylabel(f"τ {labels[j]} [N m]", fontsize=8)
    ax[0, 0].legend(fontsize=8)
    ax[2, 0].set_xlabel("t [s]")
    ax[2, 1].set_xlabel("t [s]")
    fig.suptitle(f"Validation trajectory: measured, true and predicted torques (relative RMS error "
                 f"{100 * result['validation_relative']:.2f} %)", fontsize=10)
    fig.tight_layout()
    fig.savefig(figures / "identification_validation.png", dpi=110)
    plt.close(fig)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None,
                        help="output directory (default: a temporary one)")
    parser.add_argument("--quick", action="store_true", help="fewer design iterations")
    parser.add_argument("--figures", default=None, help="write the figures into this folder")
    args = parser.parse_args(argv)
    r = run(args.out, args.quick, args.figures)
    print(f"output: {r['out']}")
    print(f"excitation: κ = {r['condition']:.1f} (random feasible start "
          f"{r['condition_random']:.1f})")
    print(f"identified with: {r['how']}")
    print(f"κ of the measured base regressor {r['identification_condition']:.1f}")
    print(f"{'base parameter':28s} {'true':>12s} {'identified':>12s} {'σ':>10s} {'z':>6s}")
    for n, tr, est, s, z in zip(r["base_names"], r["truth"], r["estimate"], r["std"], r["z"],
                                strict=True):
        print(f"{n:28s} {tr:12.5g} {est:12.5g} {s:10.3g} {z:6.2f}")
    print(f"max |z| = {r['max_abs_z']:.2f}")
    print("validation RMS error per joint [N m]:", np.array2string(r["validation_rms_error"],
                                                                   precision=3))
    print(f"validation relative RMS error: {100 * r['validation_relative']:.3f} %")
    print(f"C control loop: {r['c_loop']}")
    if r.get("c_loop") == "ran":
        print(f"  {r['c_steps']} steps at {LOOP_RATE:g} Hz, max |τ_C − τ_Python| = "
              f"{r['c_max_torque_difference']:.3g} N m (max |τ| {r['c_max_torque']:.4g} N m)")
        print(f"  the exported (physically consistent) model against the true torques: "
              f"{100 * r['validation_consistent_relative']:.3f} % relative RMS")


if __name__ == "__main__":
    main()
