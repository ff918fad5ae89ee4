"""Minimal reproductions of Pinocchio's limits on models with mimic joints (docs/pinocchio-mimic.md).

Run: ``python docs/pinocchio_mimic_limits.py`` (needs only ``pin`` and numpy). It prints the
Markdown table of docs/pinocchio-mimic.md. The model is self-contained (no exo_bench import): one
telescopic rod in space, revolute z, revolute -y, a prismatic length and a prismatic *mimic* of the
length with multiplier 0.5 carrying the middle mass, plus a second rod on a revolute mimic that
levels its frame, as in exo-bench's URDF. The same URDF with the mimic tags removed (the mimic
joints then independent) is the control: there every function runs and every check holds.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

_LIMIT = '<limit effort="1e6" velocity="1e6" lower="-1e3" upper="1e3"/>'


def _joint(name, kind, parent, child, axis, mimic=None):
    m = f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]}" offset="0"/>' if mimic else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="{axis}"/>{_LIMIT}{m}</joint>'
    )


def _link(name, mass=0.0):
    inertial = (
        (
            f'<inertial><origin xyz="0 0 0"/><mass value="{mass}"/>'
            '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>'
        )
        if mass
        else ""
    )
    return f'<link name="{name}">{inertial}</link>'


def urdf(mimic: bool = True) -> str:
    """Two spatial rods; ``mimic=False`` drops the mimic tags (the joints become independent)."""
    mm = (lambda j, k: (j, k)) if mimic else (lambda j, k: None)
    parts = [
        '<?xml version="1.0"?><robot name="rods">',
        _link("support"),
        _joint("A_phi", "revolute", "support", "A_yaw", "0 0 1"),
        _link("A_yaw"),
        _joint("A_psi", "revolute", "A_yaw", "A_frame", "0 -1 0"),
        _link("A_frame", 1.0),
        _joint("A_len", "prismatic", "A_frame", "A_end", "1 0 0"),
        _link("A_end", 2.0),
        _joint("A_mid", "prismatic", "A_frame", "A_mid", "1 0 0", mm("A_len", 0.5)),
        _link("A_mid", 3.0),
        _joint("B_undo", "revolute", "A_end", "B_level", "0 -1 0", mm("A_psi", -1.0)),
        _link("B_level"),
        _joint("B_phi", "revolute", "B_level", "B_yaw", "0 0 1"),
        _link("B_yaw"),
        _joint("B_psi", "revolute", "B_yaw", "B_frame", "0 -1 0"),
        _link("B_frame", 0.5),
        _joint("B_len", "prismatic", "B_frame", "B_end", "1 0 0"),
        _link("B_end", 1.5),
        "</robot>",
    ]
    return "".join(parts)


def build(mimic: bool = True) -> pin.Model:
    model = pin.buildModelFromXML(urdf(mimic), mimic=mimic)
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    return model


def state(model: pin.Model, seed: int):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.0, 1.0, model.nq)
    for j in range(1, model.njoints):  # lengths of the rods positive
        if model.names[j].endswith("_len"):
            q[model.idx_qs[j]] = rng.uniform(0.3, 1.2)
    return q, rng.uniform(-2, 2, model.nv), rng.uniform(-2, 2, model.nv)


def _first_line(e: BaseException) -> str:
    return " ".join(str(e).split())[:160]


def refused(model: pin.Model) -> list[tuple[str, str]]:
    """Each function that pin 4.1 refuses (or accepts) on this model, with its message."""
    q, v, a = state(model, 0)
    tau = pin.rnea(model, pin.Data(model), q, v, a)
    calls = {
        "aba": lambda d: pin.aba(model, d, q, v, tau),
        "forwardDynamics": lambda d: pin.forwardDynamics(model, d, q, v, tau, np.zeros((0, model.nv)), np.zeros(0)),
        "computeMinverse": lambda d: pin.computeMinverse(model, d, q),
        "computeRNEADerivatives": lambda d: pin.computeRNEADerivatives(model, d, q, v, a),
        "computeABADerivatives": lambda d: pin.computeABADerivatives(model, d, q, v, tau),
        "computeAllTerms": lambda d: pin.computeAllTerms(model, d, q, v),
        "computeKineticEnergy": lambda d: pin.computeKineticEnergy(model, d, q, v),
        "computePotentialEnergy": lambda d: pin.computePotentialEnergy(model, d, q),
        "computeMechanicalEnergy": lambda d: pin.computeMechanicalEnergy(model, d, q, v),
    }
    out = []
    for name, call in calls.items():
        try:
            call(pin.Data(model))
            out.append((name, "runs"))
        except Exception as e:  # noqa: BLE001 - the message is what we report
            out.append((name, f"refused: {type(e).__name__}: {_first_line(e)}"))
    return out


def coriolis_residual(model: pin.Model, samples: int = 20) -> float:
    """max |C(q, v) v + g(q) - rnea(q, v, 0)| over seeded states (``g = rnea(q, 0, 0)``)."""
    worst = 0.0
    for s in range(samples):
        q, v, _ = state(model, s)
        data = pin.Data(model)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        g = pin.rnea(model, pin.Data(model), q, np.zeros(model.nv), np.zeros(model.nv))
        h = pin.rnea(model, pin.Data(model), q, v, np.zeros(model.nv))
        worst = max(worst, float(np.abs(C @ v + g - h).max()))
    return worst


def crba_reuse_difference(model: pin.Model, samples: int = 20) -> float:
    """max |crba on one reused Data - crba on a fresh Data| over consecutive seeded states."""
    reused = pin.Data(model)
    worst = 0.0
    for s in range(samples):
        q, _, _ = state(model, s)
        a = pin.crba(model, reused, q).copy()
        b = pin.crba(model, pin.Data(model), q).copy()
        worst = max(worst, float(np.abs(np.triu(a) - np.triu(b)).max()))
    return worst


def table() -> str:
    with_mimic, without = build(True), build(False)
    rows = [
        "| function | with mimic joints (nv = %d) | without (nv = %d) |" % (with_mimic.nv, without.nv),
        "|---|---|---|",
    ]
    for (name, a), (_, b) in zip(refused(with_mimic), refused(without)):
        rows.append(f"| `{name}` | {a} | {b} |")
    rows.append(
        f"| `computeCoriolisMatrix`: max abs(C v + g - rnea(q, v, 0)), 20 states | {coriolis_residual(with_mimic):.3g} "
        f"| {coriolis_residual(without):.3g} |"
    )
    rows.append(
        f"| `crba` on a reused Data minus on a fresh Data, max abs, 20 states | {crba_reuse_difference(with_mimic):.3g} "
        f"| {crba_reuse_difference(without):.3g} |"
    )
    return "\n".join(rows)


if __name__ == "__main__":
    print(f"pin {pin.__version__}\n")
    print(table())
