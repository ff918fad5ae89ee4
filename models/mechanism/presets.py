"""The paper's models as presets, generators for chains and random trees, and reading a mechanism (a
preset's name or a JSON file) and the other files a user gives.

Masses and fractions come from section 7 of the paper (the five-link
exoskeleton): link masses ``m1 = m4 = 2.91 kg``, ``m2 = m3 = 8.93 kg``,
``m5 = 28.93 kg``, split 1/4 at each joint end and 1/2 on the rod, with middle
fractions ``n11 = n41 = 0.595``, ``n21 = n31 = 0.545``, ``n51 = 0.5``. The smaller
figures (1, 2a, 2b, 5) print no numbers; they reuse the leg links of Fig. 6
(shin, thigh), which is our assumption.

Topology of Fig. 6 (the figure itself is lost, this is our reading of the
text): 1 stance shin from the support point up, 2 stance thigh up to the hip;
the hip is a branch point carrying 3 the swing thigh and 4 the swing shin,
both reversed (``sign = -1``: they hang down while their angles are measured
like the stance leg's), and 5 the trunk up from the hip.

**Reading what users give us**: a mechanism (a preset's name or a JSON file), JSON and TOML files.

One reader for every file the suite takes from a user, so that every I/O and decoding error
names the file and says what was expected: a missing file, a folder, an unreadable or binary
file (not UTF-8) and invalid JSON or TOML each give one ``ValueError`` line.
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.validation import DuplicateKey, loads

G = 9.81


def split_mass(m: float) -> tuple[float, float, float]:
    """The paper's split: 1/4 at each joint end, 1/2 on the rod."""
    return (m / 4, m / 2, m / 4)


SHIN = (split_mass(2.91), 0.595)
THIGH = (split_mass(8.93), 0.545)
TRUNK = (split_mass(28.93), 0.500)


def _whole(preset: str, field: str, value: object, expected: str, ok: Callable[[int], bool]) -> int:
    """``value`` as an int, checked before it names anything: a ValueError naming the preset, the field
    and the expected type for a bool, a float, a string or an int outside ``ok`` (``human(True)`` was
    refused as "human-Trued", ``human(2.0)`` named "human-2.0d")."""
    if not isinstance(value, int | np.integer) or isinstance(value, bool) or not ok(int(value)):
        raise ValueError(f"{preset}: field {field!r}: expected an integer, {expected}, got {value!r}")
    return int(value)


def _check_dim(preset: str, dim: object) -> int:
    return _whole(preset, "dim", dim, "2 or 3", lambda d: d in (2, 3))


def _nlinks(preset: str, nlinks: object) -> int:
    return _whole(preset, "nlinks", nlinks, ">= 1", lambda n: n >= 1)


def _mech(name, dim, parent, sign, parts, names) -> Mechanism:
    return Mechanism(
        dim=dim,
        g=G,
        parent=tuple(parent),
        sign=tuple(sign),
        masses=tuple(p[0] for p in parts),
        n=tuple(p[1] for p in parts),
        names=tuple(names),
        name=name,
    )


def fig1(dim: int = 2) -> Mechanism:
    """Fig. 1: one link hinged at the support point."""
    dim = _check_dim("fig1", dim)
    return _mech(f"fig1-{dim}d", dim, [-1], [1], [SHIN], ["shin"])


def fig2a(dim: int = 2) -> Mechanism:
    """Fig. 2a: two links in series (eq. 4, upper signs)."""
    dim = _check_dim("fig2a", dim)
    return _mech(f"fig2a-{dim}d", dim, [-1, 0], [1, 1], [SHIN, THIGH], ["shin", "thigh"])


def fig2b(dim: int = 2) -> Mechanism:
    """Fig. 2b: two links with a branch point at B, the second reversed (eq. 4, lower signs)."""
    dim = _check_dim("fig2b", dim)
    return _mech(f"fig2b-{dim}d", dim, [-1, 0], [1, -1], [SHIN, THIGH], ["shin", "thigh"])


def fig5(dim: int = 2) -> Mechanism:
    """Fig. 5: four links, branch point between links 2 and 3 (eq. 20: ``a11 + a12 - a13 - a14``)."""
    dim = _check_dim("fig5", dim)
    return _mech(
        f"fig5-{dim}d",
        dim,
        [-1, 0, 1, 2],
        [1, 1, -1, -1],
        [SHIN, THIGH, THIGH, SHIN],
        ["stance_shin", "stance_thigh", "swing_thigh", "swing_shin"],
    )


def exo5(dim: int = 3) -> Mechanism:
    """Fig. 6: the five-link exoskeleton as a tree (stance leg, swing leg from the hip, trunk)."""
    dim = _check_dim("exo5", dim)
    return _mech(
        f"exo5-{dim}d",
        dim,
        [-1, 0, 1, 2, 1],
        [1, 1, -1, -1, 1],
        [SHIN, THIGH, THIGH, SHIN, TRUNK],
        ["stance_shin", "stance_thigh", "swing_thigh", "swing_shin", "trunk"],
    )


def chain(nlinks: int, dim: int = 2, seed: int | None = None) -> Mechanism:
    """An n-link serial chain (Fig. 2a style). With a seed, masses and fractions are random."""
    nlinks, dim = _nlinks("chain", nlinks), _check_dim("chain", dim)
    if seed is None:
        parts = [(SHIN, THIGH)[i % 2] for i in range(nlinks)]
        return _mech(
            f"chain{nlinks}-{dim}d",
            dim,
            range(-1, nlinks - 1),
            [1] * nlinks,
            parts,
            [f"link{i + 1}" for i in range(nlinks)],
        )
    seed = _whole("chain", "seed", seed, ">= 0 or None", lambda s: s >= 0)
    rng = np.random.default_rng(seed)
    masses, fr = _random_masses(rng, nlinks)
    return Mechanism(
        dim=dim,
        g=G,
        parent=tuple(range(-1, nlinks - 1)),
        sign=(1,) * nlinks,
        masses=masses,
        n=fr,
        name=f"chain{nlinks}-{dim}d-seed{seed}",
    )


def _random_masses(rng: np.random.Generator, nlinks: int):
    masses = tuple(tuple(float(x) for x in rng.uniform(0.2, 3.0, 3)) for _ in range(nlinks))
    fr = tuple(float(x) for x in rng.uniform(0.1, 0.9, nlinks))
    return masses, fr


def random_tree(nlinks: int, dim: int, seed: int) -> Mechanism:
    """A seeded random tree: each link hangs from a random earlier link or from the
    support point (so a tree may have several roots), random signs, masses in [0.2, 3] kg and fractions in [0.1, 0.9]."""
    nlinks, dim = _nlinks("random_tree", nlinks), _check_dim("random_tree", dim)
    seed = _whole("random_tree", "seed", seed, ">= 0", lambda s: s >= 0)
    rng = np.random.default_rng(seed)
    parent = [-1] + [int(rng.integers(-1, i)) for i in range(1, nlinks)]
    sign = [1] + [int(rng.choice([-1, 1])) for _ in range(1, nlinks)]
    masses, fr = _random_masses(rng, nlinks)
    return Mechanism(
        dim=dim,
        g=G,
        parent=tuple(parent),
        sign=tuple(sign),
        masses=masses,
        n=fr,
        name=f"tree{nlinks}-{dim}d-seed{seed}",
    )


def _preset(f: Callable[[int], Mechanism], d: int) -> Callable[[], Mechanism]:
    return lambda: f(d)


PRESETS: dict[str, Callable[[], Mechanism]] = {}
for _fn in (fig1, fig2a, fig2b, fig5, exo5):
    for _dim in (2, 3):
        PRESETS[f"{_fn.__name__}-{_dim}d"] = _preset(_fn, _dim)


def preset_descriptions() -> dict[str, str]:
    out = {}
    for key, make in PRESETS.items():
        m = make()
        base = globals()[key.split("-")[0]].__doc__.strip().splitlines()[0]
        out[key] = f"{m.dim}D, {m.nlinks} link(s): {base}"
    return out


def human(dim: int = 2, body_mass: float = 56.7, stature: float = 1.75) -> Mechanism:
    """A human-proportioned walker with feet: Winter's segments scaled by body mass and stature.

    Links (models/mechanism/anthropometry.py gives the numbers and their sources):

    * link 1, ``root``: a massless rod from the support point O to the hips. Its angle(s) and length are the
      hips' position, so the model is free to move: O carries no load when the root's generalised
      forces are zero, and every ground force goes through contact (``f_ext``).
    * link 2, ``hat``: head, arms and trunk, from the hips (greater trochanter) up to the top of the head.
    * links 3-5 and 7-9, ``right_thigh``, ``right_leg``, ``right_foot`` and the left ones: thigh (hip to knee),
      leg (knee to ankle), and Winter's foot segment (ankle to the head of metatarsal II, the toe's
      contact point, its end mass). They hang from their parents with ``sign = -1``, so their angles
      are Winter's segment angles (of the vector from the distal to the proximal joint).
    * links 6 and 10, ``right_heel``, ``left_heel``: a short rod from the ankle back to the heel's contact
      point (its end mass). The heel is a rod of its own because a rod starts at its parent's end
      point: the ankle, not the heel, must end the leg for the ankle moment to be Winter's. The
      heel and foot rods' relative angle is a joint the foot's tissue holds (a stiff "arch"
      moment in simulation, a constraint in collocation). It carries 10 % of the foot's mass,
      taken from the foot rod's ankle mass, so the foot's total is Winter's; the foot's centre of
      mass moves 0.1 x 0.049 H (8 mm at 1.75 m) towards the heel.

    Every segment's three masses reproduce its mass, centre of mass and moment of inertia across
    the rod (:func:`exo_bench.models.mechanism.anthropometry.point_masses`). Defaults: the normative subject
    of models/gait/normative.py (56.7 kg) and the suite's stature (1.75 m). Standing:
    :func:`human_standing`.
    """
    from exo_bench.models.mechanism import anthropometry as a

    dim = _check_dim("human", dim)
    a.check_body(body_mass, stature)
    foot, n_foot = a.point_masses(a.FOOT, body_mass)
    heel = 0.1 * sum(foot)
    foot = (foot[0] - heel, foot[1], foot[2])
    parts = [((0.0, 0.0, 0.0), 0.5), a.point_masses(a.hat_to_vertex(), body_mass)]
    leg = [a.point_masses(a.THIGH, body_mass), a.point_masses(a.LEG, body_mass), (foot, n_foot)]
    parts += 2 * (leg + [((0.0, 0.0, heel), 0.5)])
    names = ["root", "hat"] + [f"{side}_{s}" for side in ("right", "left") for s in ("thigh", "leg", "foot", "heel")]
    parent = [-1, 0, 0, 2, 3, 3, 0, 6, 7, 7]
    return _mech(f"human-{dim}d", dim, parent, [1, 1] + [-1] * 8, parts, names)


def human_standing(mech: Mechanism, stature: float = 1.75, lean: float = 0.0) -> np.ndarray:
    """``q (1, dof)`` of :func:`human` standing with both feet flat on the floor (the heel and toe contact
    points at height 0), the body straight and leaning forward by ``lean`` (rad) about the ankles (0:
    upright, the hips above O). In 3D O lies 0.5 m behind the hips (a vertical root rod is where the 3D
    chart is singular, eq. 7) and the legs, near vertical, sit near that chart's poles, so 3D standing is a
    kinematic pose only. Rod lengths are the anthropometric ones for ``stature``."""
    from exo_bench.models.mechanism import anthropometry as a

    body = np.pi / 2 - lean  # the angle of thighs, legs (distal -> proximal) and HAT
    heel = (a.HEEL_FORWARD, a.ANKLE_HEIGHT)  # ankle minus heel point: (forward, up) / H
    toe = (a.TOE_FORWARD, -a.ANKLE_HEIGHT)  # toe point minus ankle
    foot_angle = np.arctan2(-toe[1], -toe[0])  # of the vector from toe to ankle (sign = -1)
    heel_angle = np.arctan2(heel[1], -heel[0])  # from heel to ankle
    leg_rods = [(body, a.THIGH.length), (body, a.LEG.length), (foot_angle, a.FOOT.length)]
    leg_rods.append((heel_angle, float(np.hypot(*heel))))
    up = (a.THIGH.length + a.LEG.length) * stature
    hip_x, hip_z = up * np.cos(body), a.ANKLE_HEIGHT * stature + up * np.sin(body)
    if mech.dim == 3:
        hip_x += 0.5
    root = (float(np.arctan2(hip_z, hip_x)), float(np.hypot(hip_z, hip_x)))
    rods = [root, (body, 1.0 - a.HIP_HEIGHT)] + 2 * leg_rods
    lengths = [rods[0][1]] + [r[1] * stature for r in rods[1:]]
    angles = [float(r[0]) for r in rods]
    if mech.dim == 2:
        return np.array([angles + lengths])
    azimuth = [0.0 if np.cos(x) >= 0 else np.pi for x in angles]  # every rod in the x-z plane
    elevation = [float(np.arcsin(np.sin(x))) for x in angles]
    return np.array([azimuth + elevation + lengths])


for _dim in (2, 3):
    PRESETS[f"human-{_dim}d"] = _preset(human, _dim)

#: Peak memory of reading a JSON file of numbers, per byte of text: measured 3.3 (200,000 samples
#: of exo5-3d states, 181 MB: the text, Python's lists and floats, the float arrays), rounded up.
READ_BYTES_PER_BYTE = 4


def regular_file(path: str | Path, what: str) -> Path:
    """``path`` as a :class:`Path` when it names an existing regular file; otherwise one
    ValueError line (no such file, a folder, a device/FIFO/socket, an unusable path)."""
    p = Path(path)
    try:
        exists, is_dir, is_file = p.exists(), p.is_dir(), p.is_file()
    except (OSError, ValueError) as e:  # a NUL character, a name too long
        raise ValueError(f"{what}: not a usable path ({getattr(e, 'strerror', None) or e})") from None
    if not exists:
        raise ValueError(f"{what}: no such file")
    if is_dir:
        raise ValueError(f"{what}: expected a file, got a folder")
    if not is_file:
        raise ValueError(f"{what}: expected a regular file, got a device, FIFO or socket")
    return p


def read_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of ``path``; ``what`` names the file's role in messages (``"states 'x.json'"``).

    Only regular files are read (a FIFO or a device such as /dev/zero would block or never end),
    and only when reading fits in the memory a run may use (:func:`exo_bench.models.machine.memory.usable_memory`)."""
    from exo_bench.models.machine.memory import usable_memory

    p = regular_file(path, what)
    size = p.stat().st_size
    limit = usable_memory()
    if limit is not None and size * READ_BYTES_PER_BYTE > limit:
        raise ValueError(
            f"{what}: {size / 1e9:.1f} GB of text would need about {size * READ_BYTES_PER_BYTE / 1e9:.0f} GB "
            f"to read, more than the {limit / 1e9:.1f} GB a run may use; split it, or give states as a "
            ".npz file"
        )
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ValueError(f"{what}: cannot read: {e.strerror}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(
            f"{what}: expected UTF-8 text, got bytes that are not (byte {e.start}: {data[e.start : e.start + 1]!r}); "
            "is this a binary file?"
        ) from None


def read_json(path: str | Path, what: str) -> Any:
    text = read_text(path, what)
    try:
        return loads(text)
    except DuplicateKey as e:
        raise ValueError(f"{what}: invalid JSON: {e}") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{what}: invalid JSON: {e}") from None
    except RecursionError:
        raise ValueError(
            f"{what}: JSON nested too deeply to read (more than Python's recursion limit of about 1000 levels)"
        ) from None


def read_toml(path: str | Path, what: str) -> dict:
    text = read_text(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{what}: invalid TOML: {e}") from None
    except RecursionError:
        raise ValueError(f"{what}: TOML nested too deeply to read") from None


def load_mechanism(spec: str | Path) -> Mechanism:
    """A preset name (see ``exo-bench presets``) or the path of a JSON file."""
    key = str(spec)
    if key in PRESETS:
        return PRESETS[key]()
    try:
        exists = Path(spec).exists()
    except (OSError, ValueError) as e:  # a NUL character, a name too long
        raise ValueError(
            f"mechanism {key!r}: not a preset and not a usable path ({getattr(e, 'strerror', None) or e})"
        ) from None
    if not exists:
        raise ValueError(f"mechanism {key!r}: not a preset ({', '.join(sorted(PRESETS))}) and no such file")
    return Mechanism.from_dict(read_json(spec, f"mechanism {key!r}"), source=str(spec))


def save_mechanism(mech: Mechanism, path: str | Path) -> None:
    """``mech`` as JSON to ``path``, whole or not at all, never through a symlink planted there
    (:func:`exo_bench.models.files.atomic_write`)."""
    from exo_bench.models.files import atomic_write

    atomic_write(path, mech.to_json() + "\n")
