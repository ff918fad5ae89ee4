"""Minimal reproductions of the two Pinocchio behaviours described in docs/pinocchio-memory.md.

Pure Pinocchio and numpy (no exo-bench code). Run: ``python docs/pinocchio_data_memory.py``
(Linux: memory is read from /proc/self/status).

1. ``pin.Data(model)`` allocates and zero-fills about ``32 nv^3`` bytes on any model, whatever
   algorithm is then called: a plain chain of revolute joints shows it. ``model.createData()``
   peaks at twice that (it returns a copy).
2. On a model with a mimic joint, ``pin.crba`` with a reused ``Data`` depends on the previous
   call: ``data.Fcrb`` is read before it is written.
"""

import time

import numpy as np
import pinocchio as pin


def status(key: str = "VmRSS") -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {key}")


def rss_bytes() -> int:
    return status("VmRSS")


def peak_of(make):
    """(object, peak RSS growth, kept RSS growth, seconds) of ``make()``; the peak is reset first."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    before = rss_bytes()
    t0 = time.perf_counter()
    obj = make()
    seconds = time.perf_counter() - t0
    return obj, status("VmHWM") - before, rss_bytes() - before, seconds


def revolute_chain(nv: int) -> pin.Model:
    """nv revolute joints in series, a 1 kg point mass at the end of each 0.1 m link."""
    model = pin.Model()
    parent = 0
    for k in range(nv):
        placement = pin.SE3(np.eye(3), np.array([0.1, 0.0, 0.0]) if k else np.zeros(3))
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{k}")
        model.appendBodyToJoint(parent, pin.Inertia.FromSphere(1.0, 0.0), pin.SE3.Identity())
    return model


def data_memory() -> None:
    print("1. pin.Data(model) on a chain of nv revolute joints (pin", pin.__version__ + "): RSS growth in MB")
    print(
        f"{'nv':>5} {'32 nv^3':>9} {'pin.Data kept':>14} {'peak':>8} {'createData kept':>16} {'peak':>8} "
        f"{'seconds':>8} {'rnea us':>8}"
    )
    for nv in (50, 100, 200, 400):
        model = revolute_chain(nv)
        data, peak, kept, seconds = peak_of(lambda: pin.Data(model))
        q = np.zeros(nv)
        t0 = time.perf_counter()
        pin.rnea(model, data, q, q, q)
        rnea = (time.perf_counter() - t0) * 1e6
        del data
        data, cpeak, ckept, _ = peak_of(model.createData)
        del data
        print(
            f"{nv:5d} {32 * nv**3 / 1e6:9.1f} {kept / 1e6:14.1f} {peak / 1e6:8.1f} {ckept / 1e6:16.1f} "
            f"{cpeak / 1e6:8.1f} {seconds:8.3f} {rnea:8.0f}"
        )
    print(
        "RNEA itself needs O(nv) memory; the nv^3 part is d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq "
        "(nv x nv x nv each) and kinematic_hessians (6 x nv x nv), all allocated in DataTpl's constructor. "
        "createData() peaks at twice the size: it returns a copy."
    )


def _joint(name: str, kind: str, parent: str, child: str, axis: str, mimic: str = "") -> str:
    """A URDF joint at the parent's origin, about or along ``axis``; ``mimic``: the joint it copies, negated."""
    copies = f'\n    <mimic joint="{mimic}" multiplier="-1" offset="0"/>' if mimic else ""
    return (
        f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 0"/>\n'
        f'    <axis xyz="{axis}"/><limit effort="1" velocity="1" lower="-3" upper="3"/>{copies}</joint>\n'
    )


def _mass(name: str) -> str:
    """A URDF link with a point mass of 1 kg at its origin."""
    return (
        f'  <link name="{name}"><inertial><origin xyz="0 0 0"/><mass value="1"/>\n'
        '    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>\n'
    )


#: Two rods, each a revolute then a prismatic joint with a point mass at its end; between them the
#: mimic joint ``undo`` turns back the first rod's angle.
URDF = (
    '<?xml version="1.0"?>\n<robot name="mimic_crba">\n  <link name="base"/>\n'
    + _joint("a", "revolute", "base", "l1", "0 -1 0")
    + '  <link name="l1"/>\n'
    + _joint("b", "prismatic", "l1", "l2", "1 0 0")
    + _mass("l2")
    + _joint("undo", "revolute", "l2", "l3", "0 -1 0", mimic="a")
    + '  <link name="l3"/>\n'
    + _joint("c", "revolute", "l3", "l4", "0 0 1")
    + '  <link name="l4"/>\n'
    + _joint("d", "prismatic", "l4", "l5", "1 0 0")
    + _mass("l5")
    + "</robot>\n"
)


def crba_with_mimic() -> None:
    print("\n2. pin.crba on a model with a mimic joint, Data reused")
    model = pin.buildModelFromXML(URDF, mimic=True)
    q0, q1 = np.array([0.3, 0.7, -0.4, 0.9]), np.array([-0.5, 0.4, 0.6, 1.1])
    fresh = np.triu(pin.crba(model, model.createData(), q1))
    data = model.createData()
    pin.crba(model, data, q0)
    reused = np.triu(pin.crba(model, data, q1))
    print(f"max |M(q1) with a reused Data - M(q1) with a fresh Data| = {np.abs(reused - fresh).max():.3g}")
    data = model.createData()
    pin.crba(model, data, q0)
    for F in data.Fcrb:
        F[...] = 0.0
    zeroed = np.triu(pin.crba(model, data, q1))
    print(f"the same after zeroing data.Fcrb: {np.abs(zeroed - fresh).max():.3g}")


if __name__ == "__main__":
    data_memory()
    crba_with_mimic()
