"""The cost of reading a states file and of writing the forces, known before either happens.

``exo-bench inverse`` holds reading the states and writing tau to ``--max-memory`` and
``--max-time`` like the method's own work (exo_bench/api/cost_model.py ``check(..., io=...)``):

* a ``.npz`` archive is judged by the **uncompressed** size of its arrays, read from the zip's
  central directory (``zipfile.ZipInfo.file_size``) and each member's ``.npy`` header (shape and
  dtype: only the first bytes of a member are inflated), so the number of samples, and with it the
  whole estimate, is known before any array is decompressed (a 7 MB archive of zeros that inflates
  to 7 GB is refused in one line);
* a JSON file is judged by its size: reading it peaks at about
  :data:`exo_bench.models.mechanism.presets.READ_BYTES_PER_BYTE` times its bytes, at :data:`JSON_BYTES_PER_SECOND`;
  its samples are known only once it is parsed, so reading is checked alone first and the whole
  run again right after parsing, before the method is prepared;
* writing tau as JSON costs :data:`WRITE_SECONDS_PER_NUMBER` per number (written in row blocks: no
  memory that grows with the batch beyond tau itself).

Rates measured on the shared 2-core machine (exo5-3d states, 50,000 samples: JSON 46 MB read in
2.0 s, 24 MB/s; a stored .npz at 770 MB/s and a deflated one at 130 MB/s of arrays; tau written
at 1.9 us per number), rounded towards slower so that a time limit is not passed by the I/O.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

JSON_BYTES_PER_SECOND = 20e6
NPZ_STORED_BYTES_PER_SECOND = 500e6
NPZ_DEFLATED_BYTES_PER_SECOND = 100e6
WRITE_SECONDS_PER_NUMBER = 2.5e-6
KEYS = ("q", "qd", "qdd")


@dataclass(frozen=True)
class StatesFile:
    """What is known of a states file before reading it: ``samples`` (None for JSON), the peak
    bytes and seconds of reading it."""

    path: str
    samples: int | None
    read_bytes: float
    read_seconds: float
    kind: str

    def io(self, dof: int, samples: int | None = None) -> tuple[float, float]:
        """``(peak bytes of reading, seconds of reading and of writing tau)`` for ``samples``."""
        s = self.samples if samples is None else samples
        return self.read_bytes, self.read_seconds + WRITE_SECONDS_PER_NUMBER * dof * (s or 0)


def npz_header(path: str | Path, what: str) -> dict[str, tuple[tuple[int, ...], np.dtype, int]]:
    """``name -> (shape, dtype, compress_type)`` of each array of a ``.npz``, read from the zip
    directory and the ``.npy`` headers without inflating the arrays; one ValueError line for a file
    that is not such an archive."""
    out = {}
    try:
        with zipfile.ZipFile(path) as zf:
            seen: set[str] = set()
            for info in zf.infolist():
                # numpy's NpzFile reads member "q" for key "q" before "q.npy": two members that one key
                # can name (or one name twice in the zip) would have the header of one checked and the
                # other loaded
                key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                if key in seen:
                    raise ValueError(
                        f"{what}: expected one member per array, got two members named {key!r} "
                        f"({info.filename!r} and an earlier one): which one numpy loads is not the one checked"
                    )
                seen.add(key)
                if not info.filename.endswith(".npy"):
                    continue
                with zf.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    if version == (1, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
                    else:
                        shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
                out[info.filename[:-4]] = (tuple(int(x) for x in shape), np.dtype(dtype), info.compress_type)
    except (zipfile.BadZipFile, EOFError) as e:
        raise ValueError(f"{what}: expected a NumPy .npz archive, got a file that is not one ({e})") from None
    except ValueError as e:  # a member that is not a .npy array
        if str(e).startswith(what):
            raise
        raise ValueError(f"{what}: cannot read the arrays: {str(e).splitlines()[0]}") from None
    except (OSError, NotImplementedError, RuntimeError) as e:
        raise ValueError(f"{what}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    return out


def peek_states(path: str, dof: int, third: str = "qdd") -> StatesFile:
    """The cost of reading the states file ``path`` (of a mechanism with ``dof`` coordinates) and,
    for a ``.npz``, its number of samples, from its headers; the file is checked to be a regular
    file (models.loading.regular_file)."""
    from exo_bench.models.mechanism.presets import READ_BYTES_PER_BYTE, regular_file

    what = f"states {path!r}"
    p = regular_file(path, what)
    if not str(path).endswith(".npz"):
        size = p.stat().st_size
        return StatesFile(str(path), None, READ_BYTES_PER_BYTE * size, size / JSON_BYTES_PER_SECOND, "json")
    arrays = npz_header(p, what)
    keys = ("q", "qd", third)
    missing = [k for k in keys if k not in arrays]
    if missing:
        raise ValueError(f"{what}: expected an object with keys {list(keys)}, got {sorted(arrays)}")
    samples, total, seconds = set(), 0.0, 0.0
    for k in keys:
        shape, dtype, compress = arrays[k]
        if dtype.kind not in "iuf":
            raise ValueError(f"{what}: field '{k}': expected an array of real numbers, got dtype {dtype}")
        if len(shape) not in (1, 2) or shape[-1] != dof:
            raise ValueError(f"{what}: field '{k}': expected shape (samples, {dof}), got {shape}")
        samples.add(shape[0] if len(shape) == 2 else 1)
        count = int(np.prod(shape))
        nbytes = count * dtype.itemsize
        total += nbytes + (0 if dtype == np.float64 else 8 * count)  # the float64 copy of another dtype
        rate = NPZ_STORED_BYTES_PER_SECOND if compress == zipfile.ZIP_STORED else NPZ_DEFLATED_BYTES_PER_SECOND
        seconds += nbytes / rate
    if "f_ext" in arrays:  # optional external forces (samples, links, 3, dim): read as the states are
        shape, dtype, compress = arrays["f_ext"]
        count = int(np.prod(shape))
        total += count * dtype.itemsize + (0 if dtype == np.float64 else 8 * count)
        rate = NPZ_STORED_BYTES_PER_SECOND if compress == zipfile.ZIP_STORED else NPZ_DEFLATED_BYTES_PER_SECOND
        seconds += count * dtype.itemsize / rate
    if len(samples) > 1:
        raise ValueError(f"{what}: q, qd and {third} must have the same number of samples, got {sorted(samples)}")
    return StatesFile(str(path), samples.pop(), total, seconds, "npz")
