"""The array gate (issue 49, models/array_gate.py): no ndarray subclass, shape, stride, dtype or offset of an
input or of ``out`` makes a public call write outside its buffer or crash, with ``check=True`` or
``check=False``; each call answers the converted states' result or a ValueError naming the argument.

A hypothesis strategy draws, for matrix-factored, newton-euler, recurrence and matrix, every public call
(inverse and forward dynamics, mass matrix, bias forces, both terms; one sample and a batch; checked and
not), one argument to spoil (an input or ``out``) and how: ``np.matrix``, a masked array, a ``memmap``, a
``recarray`` view, a user's subclass, a wrong shape, a stride, another dtype, an unaligned offset, a
read-only ``out``. ``out`` lies in a buffer between guard bytes, which must be left as they were. It all
runs in a CHILD process: a heap corruption or a segfault fails this test instead of killing the run. Before
the gate, an ``np.matrix`` as ``out`` made the compiled kernels write S x dof doubles past the buffer
(``corrupted double-linked list``, exit 134, or SIGSEGV), and ``np.matrix`` inputs with ``check=False``
raised numba's TypingError."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.array_gate import as_out, as_states, describe, is_plain
from exo_bench.models.presets import exo5

CHILD = textwrap.dedent(
    r'''
    import os, sys, tempfile
    import numpy as np
    from hypothesis import given, settings, HealthCheck, strategies as st
    from exo_bench import prepare
    from exo_bench.models.motion import random_states
    from exo_bench.models.presets import exo5

    MECH = exo5(3)
    DOF = MECH.dof
    S = 3
    METHODS = ("matrix-factored", "newton-euler", "recurrence", "matrix")
    MODELS = {m: prepare(MECH, m) for m in METHODS}
    CALLS = {  # name: (argument names, has out, batch only)
        "inverse_dynamics": (("q", "qd", "qdd"), True, False),
        "forward_dynamics": (("q", "qd", "tau"), True, False),
        "mass_matrix": (("q",), False, False),
        "bias_forces": (("q", "qd"), False, False),
        "mass_matrix_and_bias": (("q", "qd"), False, True),
    }
    KINDS = ("matrix", "masked", "memmap", "recarray", "subclass", "shape", "stride", "float32", "int64",
             "big-endian", "complex", "offset", "read-only")
    GUARD = 16
    SENTINEL = -7.25e77
    TMP = tempfile.mkdtemp()

    class Mine(np.ndarray):
        pass

    def states(model, one):
        q, qd, qdd = random_states(MECH, S, 3)
        tau = model.inverse_dynamics(q, qd, qdd)
        arrays = {"q": q, "qd": qd, "qdd": qdd, "tau": tau}
        return {k: (np.ascontiguousarray(v[0]) if one else v) for k, v in arrays.items()}

    def spoil(a, kind, name):
        """``a`` (plain float64) made into the drawn form: (the array, its values as float64 or None)."""
        if kind == "matrix":
            return (np.matrix(a) if a.ndim <= 2 else a), np.atleast_2d(a)
        if kind == "masked":
            return np.ma.masked_array(a, mask=np.zeros(a.shape, bool)), a
        if kind == "memmap":
            path = os.path.join(TMP, f"{name}-{np.random.randint(1 << 30)}.dat")
            m = np.memmap(path, dtype=np.float64, mode="w+", shape=a.shape)
            m[...] = a
            return m, a
        if kind == "recarray":
            return a.view(np.recarray), a
        if kind == "subclass":
            return a.view(Mine), a
        if kind == "shape":
            return np.zeros(a.shape[:-1] + (a.shape[-1] + 1,)), None
        if kind == "stride":
            b = np.repeat(a, 2, axis=-1)[..., ::2]
            return b, a
        if kind == "float32":
            b = a.astype(np.float32)
            return b, b.astype(np.float64)
        if kind == "int64":
            b = np.round(a * 100).astype(np.int64)
            b[..., 2 * MECH.nlinks:] = np.abs(b[..., 2 * MECH.nlinks:]) + 1
            return b, b.astype(np.float64)
        if kind == "big-endian":
            return a.astype(">f8"), a
        if kind == "complex":
            return a.astype(np.complex128), None
        if kind == "offset":
            raw = np.zeros(a.size * 8 + 1, np.uint8)
            b = np.frombuffer(raw.data, dtype=np.float64, count=a.size, offset=1).reshape(a.shape)
            b[...] = a
            return b, a
        if kind == "read-only":
            b = a.copy()
            b.flags.writeable = False
            return b, a
        raise AssertionError(kind)

    def guarded_out(shape, kind):
        """``out`` of ``shape`` between guard bytes (the whole buffer, the view)."""
        size = int(np.prod(shape))
        buf = np.full(size + 2 * GUARD + 1, SENTINEL)
        plain = buf[GUARD : GUARD + size].reshape(shape)
        if kind is None:
            return buf, plain
        if kind == "matrix":
            return buf, plain.reshape(shape[0] if len(shape) == 2 else 1, -1).view(np.matrix)
        if kind == "masked":
            return buf, np.ma.masked_array(plain)
        if kind == "memmap":
            path = os.path.join(TMP, f"out-{np.random.randint(1 << 30)}.dat")
            m = np.memmap(path, dtype=np.float64, mode="w+", shape=(size + 2 * GUARD,))
            m[:] = SENTINEL
            return m, m[GUARD : GUARD + size].reshape(shape)
        if kind == "recarray":
            return buf, plain.view(np.recarray)
        if kind == "subclass":
            return buf, plain.view(Mine)
        if kind == "shape":
            return buf, buf[GUARD : GUARD + size - 1]
        if kind == "stride":
            return buf, buf[GUARD : GUARD + size].reshape(shape)[..., ::2] if shape[-1] > 1 else buf[GUARD::2]
        if kind == "float32":
            return buf, plain.view(np.float32)
        if kind == "int64":
            return buf, plain.view(np.int64)
        if kind == "big-endian":
            return buf, plain.view(">f8")
        if kind == "complex":
            return buf, buf[GUARD : GUARD + size - size % 2].view(np.complex128)
        if kind == "offset":
            raw = buf.view(np.uint8)[GUARD * 8 + 1 : GUARD * 8 + 1 + size * 8]
            return buf, np.frombuffer(raw, dtype=np.float64).reshape(shape) if raw.size == size * 8 else raw
        if kind == "read-only":
            plain.flags.writeable = False
            return buf, plain
        raise AssertionError(kind)

    def guards_kept(buf, size):
        b = np.asarray(buf)
        return bool((b[:GUARD] == SENTINEL).all() and (b[GUARD + size :] == SENTINEL).all())

    def result_of(model, call, args, check, out):
        kw = {"check": check} if out is None else {"check": check, "out": out}
        return getattr(model, call)(*args, **kw)

    def close(got, want):
        got = [got] if not isinstance(got, tuple) else list(got)
        want = [want] if not isinstance(want, tuple) else list(want)
        for g, w in zip(got, want):
            g = np.asarray(g)
            if g.size != w.size or type(g) is not np.ndarray:
                return False
            g = g.reshape(w.shape)
            if not np.allclose(g, w, rtol=1e-10, atol=1e-9 * max(1.0, np.abs(w).max())):
                return False
        return True

    @settings(max_examples=int(os.environ.get("GATE_EXAMPLES", "400")), deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(
        method=st.sampled_from(METHODS),
        call=st.sampled_from(sorted(CALLS)),
        one=st.booleans(),
        check=st.booleans(),
        target=st.integers(0, 3),
        kind=st.sampled_from(KINDS),
        with_out=st.booleans(),
    )
    def run(method, call, one, check, target, kind, with_out):
        model = MODELS[method]
        names, has_out, batch_only = CALLS[call]
        data = states(model, one)
        args = [data[n] for n in names]
        spoiled = "out" if (has_out and target == len(names)) else names[min(target, len(names) - 1)]
        plain_args = list(args)
        values = None
        if spoiled != "out":
            k = names.index(spoiled)
            args[k], values = spoil(args[k], kind, spoiled)
            if values is not None:  # the reference: the same values as a plain array of the spoiled one's shape
                plain_args[k] = np.ascontiguousarray(values, dtype=np.float64)
        shape = plain_args[0].shape if plain_args[0] is not None else data["q"].shape
        out_kind = kind if spoiled == "out" else None
        buf, out = (None, None)
        if has_out and (with_out or spoiled == "out"):
            buf, out = guarded_out(shape, out_kind)
        try:
            got = result_of(model, call, args, check, out)
        except ValueError as e:
            msg = str(e)
            named = f"'{spoiled}'" in msg or (spoiled == "q" and "q of shape" in msg)
            expected_refusal = (
                spoiled == "out"
                or not check
                or values is None
                or (batch_only and one)
            )
            assert named or (batch_only and one and "q of shape" in msg), (method, call, spoiled, kind, msg)
            assert expected_refusal, (method, call, spoiled, kind, check, "refused a convertible input", msg)
        else:
            assert spoiled != "out", (method, call, kind, "accepted a spoiled out")
            assert check or kind == "read-only", (method, call, spoiled, kind, "check=False accepted a spoiled input")
            assert values is not None, (method, call, spoiled, kind, "accepted what has no values")
            want = result_of(model, call, plain_args, True, None)
            assert close(got, want), (method, call, spoiled, kind, one, check)
            assert all(type(r) is np.ndarray for r in (got if isinstance(got, tuple) else (got,)))
            if out is not None:
                assert got is out
        if buf is not None:
            assert guards_kept(buf, int(np.prod(shape))), (method, call, spoiled, kind, "wrote past out")

    run()
    print("ok")
    '''
)


def test_no_form_of_an_array_corrupts_memory_or_goes_unnamed_in_a_child_process():
    env = {**os.environ, "GATE_EXAMPLES": os.environ.get("GATE_EXAMPLES", "400")}
    r = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=3000, env=env)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), (r.returncode, r.stdout[-3000:], r.stderr[-6000:])


@pytest.mark.parametrize("kind", ["matrix", "masked", "memmap", "recarray", "subclass"])
def test_np_matrix_and_other_subclasses_as_out_are_refused_naming_out(tmp_path, kind):
    """The case of the heap corruption, in this process too (the gate refuses before any kernel runs):
    every subclass of ndarray as ``out``, checked or not, one sample or a batch, is a ValueError naming
    ``out``, the expected and the actual array; the buffer is not written."""
    mech = exo5(3)
    model = prepare(mech, "matrix-factored")
    rng = np.random.default_rng(0)
    q = np.abs(rng.standard_normal((4, mech.dof))) + 0.5
    for one in (True, False):
        args = [np.ascontiguousarray(q[0]) if one else q] * 3
        base = np.zeros((1, mech.dof) if one else q.shape)
        if kind == "matrix":
            out = np.matrix(base)
        elif kind == "masked":
            out = np.ma.masked_array(base.reshape(args[0].shape))
        elif kind == "memmap":
            out = np.memmap(tmp_path / f"o{one}.dat", dtype=np.float64, mode="w+", shape=args[0].shape)
        elif kind == "recarray":
            out = base.reshape(args[0].shape).view(np.recarray)
        else:
            out = base.reshape(args[0].shape).view(type("Mine", (np.ndarray,), {}))
        for check in (True, False):
            with pytest.raises(ValueError, match=r"field 'out': expected a writable C-ordered float64 array .*got "):
                model.inverse_dynamics(*args, check=check, out=out)
            assert not np.asarray(out).any()


def test_the_gate_api():
    """The gate's own answers: what is plain, what is converted, what is refused and how it is named."""
    a = np.zeros(3)
    assert is_plain(a) and not is_plain(a.view(np.matrix)) and not is_plain(a.astype(">f8"))
    assert not is_plain(np.zeros(6)[::2]) and not is_plain(np.frombuffer(bytes(25), np.float64, 3, 1))
    q, qd, _ = as_states((np.matrix([[1.0, 2.0, 3.0]]), [[0, 0, 0]], None), ("q", "qd", "qdd"), 3, "m", True)
    assert type(q) is np.ndarray and q.shape == (1, 3) and qd.dtype == np.float64
    with pytest.raises(ValueError, match=r"m: field 'q': expected C-ordered float64 .* got numpy.matrix"):
        as_states((np.matrix([[1.0, 2.0, 3.0]]),), ("q",), 3, "m", False)
    with pytest.raises(ValueError, match=r"field 'qd': .*\(q: \(1, 3\)\)"):
        as_states((np.zeros((1, 3)), np.zeros(3)), ("q", "qd"), 3, "m", False)
    with pytest.raises(ValueError, match=r"field 'out': .*shape \(3,\).*got float32 array"):
        as_out(np.zeros(3, np.float32), (3,), "m")
    with pytest.raises(ValueError, match=r"field 'out': .*overlaps 'q'"):
        as_out(a, (3,), "m", (a,), ("q",))
    assert "not aligned" in describe(np.frombuffer(bytes(25), np.float64, 3, 1))
    assert as_out(a, (3,), "m") is a
