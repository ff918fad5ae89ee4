"""Winter's Appendix A stride as curves over the whole cycle, for :mod:`.comparison`.

:mod:`exo_bench.models.gait.normative` keeps the peaks and the thigh and leg angles; this module keeps the
curves the stride is compared with, per frame from the right heel contact (frame 28) to the next (frame
97), read from the same Excel transcription (:data:`exo_bench.models.gait.normative.SOURCE`) by
:func:`from_workbook` (``python -m exo_bench.bench.studies.stride.winter Winter_Appendix_data.xlsx``
prints :data:`TABLE` again and says whether it matches):

* ``t`` s (Table A.3), from the heel contact;
* ``ankle_m``, ``knee_m``, ``hip_m`` N·m (Table A.5: the moment on the foot at the ankle, on the leg at
  the knee, on the thigh at the hip). **Sign**: Winter's tables give every load as it acts on the
  segment named, counter-clockwise positive with the subject walking in +x: the moment the proximal
  segment exerts on the distal one at their joint. A plantarflexor moment at push-off is negative;
* ``grf_x``, ``grf_y`` N (Table A.5, the ground's force on the right foot: fore-aft, vertical);
* ``foot``, ``leg``, ``thigh``, ``hat`` degrees (Table A.3, THETA): the angle of the vector from the
  distal to the proximal end of the segment (the foot: from the metatarsal to the ankle; 1/2 HAT: from
  the hip up), counter-clockwise from +x;
* ``w_foot``, ``w_leg``, ``w_thigh``, ``w_hat`` rad/s (Table A.3, OMEGA).

Joint powers are ``moment x (omega_distal - omega_proximal)`` (:func:`joint_powers`), the definition
:func:`exo_bench.bench.studies.stride.actuators.powers` uses for the model. Winter's Table A.7 lists
muscle powers only for frames 2-70 of the transcription, so the whole-cycle curve is computed. Over the
stance frames both cover (28-70) it equals Table A.7 within 0.26 W at the knee and 0.48 W at the hip;
at the ankle it differs by up to 36.9 W (frame 65: 217 W against 254 W), and Table A.4's ankle angular
velocity times the moment does not give Table A.7 either (up to 41 W off): the transcription does not
show how Table A.7's ankle column was computed.

The transcription gives one subject, so no inter-subject spread: a curve's scale is its own RMS.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np

from exo_bench.models.gait.normative import HEEL_CONTACT, NEXT_HEEL_CONTACT, SUBJECT_MASS

COLUMNS = (
    "frame",
    "t",
    "ankle_m",
    "knee_m",
    "hip_m",
    "grf_x",
    "grf_y",
    "foot",
    "leg",
    "thigh",
    "hat",
    "w_foot",
    "w_leg",
    "w_thigh",
    "w_hat",
)
#: (sheet prefix, column of the sheet) of every column but ``frame``.
_SOURCE = {
    "t": ("A3", 3),
    "ankle_m": ("A5", 9),
    "knee_m": ("A5", 16),
    "hip_m": ("A5", 24),
    "grf_x": ("A5", 4),
    "grf_y": ("A5", 5),
    "foot": ("A3", 4),
    "leg": ("A3", 14),
    "thigh": ("A3", 24),
    "hat": ("A3", 34),
    "w_foot": ("A3", 5),
    "w_leg": ("A3", 15),
    "w_thigh": ("A3", 25),
    "w_hat": ("A3", 35),
}
#: Joint -> (moment column, distal segment's omega, proximal segment's omega).
JOINTS = {
    "ankle": ("ankle_m", "w_foot", "w_leg"),
    "knee": ("knee_m", "w_leg", "w_thigh"),
    "hip": ("hip_m", "w_thigh", "w_hat"),
}
#: Frames of the right foot's stance within the stride (heel contact to toe-off, Table A.3 STATE).
STANCE_FRAMES = (HEEL_CONTACT, 70)
MASS = SUBJECT_MASS

TABLE = """\
28 0 -1.7 -33.8 -54.4 37.3 87.1 171.7 108.4 109.6 96.8 -3.48 -1.99 -0.39 0.41
29 0.014 4.6 -19.9 -37.6 -4.2 192.6 168.4 106.6 109.3 97.1 -4.32 -2.33 -0.41 0.28
30 0.029 8.3 -7.6 -23.5 -43.7 304.1 164.6 104.6 109 97.2 -4.74 -2.5 -0.41 0.12
31 0.043 2.8 -4.5 -20.8 -74 404.2 160.6 102.5 108.6 97.3 -4.63 -2.61 -0.36 -0.06
32 0.057 6.9 7.8 -11.1 -91.9 476.6 157 100.3 108.4 97.1 -4.04 -2.68 -0.29 -0.25
33 0.072 4.6 14.5 -7.8 -102.7 521.7 154 98.1 108.2 96.9 -3.14 -2.69 -0.26 -0.42
34 0.086 5 24.8 -0.4 -110.5 552.9 151.9 95.9 107.9 96.4 -2.11 -2.6 -0.37 -0.55
35 0.1 2.6 31.6 4.7 -114.2 579.8 150.6 93.8 107.6 96 -1.19 -2.41 -0.64 -0.59
36 0.114 -0.5 35 7.3 -110.5 599.6 149.9 91.9 106.9 95.5 -0.52 -2.15 -1.04 -0.56
37 0.129 0.2 37.8 9.9 -98.1 604.5 149.7 90.3 105.9 95 -0.16 -1.88 -1.45 -0.49
38 0.143 -3.5 32.5 5 -79.8 589.9 149.7 88.9 104.5 94.7 -0.03 -1.64 -1.81 -0.43
39 0.157 -5.1 28.1 3 -62 558.1 149.7 87.6 102.9 94.3 -0.03 -1.46 -2.05 -0.41
40 0.172 -6.6 24.8 4.7 -48.7 516.7 149.6 86.5 101.2 94 -0.08 -1.33 -2.18 -0.47
41 0.186 -10.5 20.2 6.5 -39.8 473.4 149.5 85.4 99.3 93.6 -0.17 -1.24 -2.19 -0.58
42 0.2 -10.6 19.8 12 -33 433.4 149.3 84.4 97.6 93 -0.29 -1.18 -2.11 -0.72
43 0.215 -14.1 15.8 12.5 -27 400.3 149 83.5 95.9 92.4 -0.46 -1.16 -1.99 -0.86
44 0.229 -18.7 10.9 10.9 -21.8 377.1 148.6 82.5 94.3 91.6 -0.65 -1.17 -1.87 -0.98
45 0.243 -22.5 7.8 10.1 -18.1 365 148 81.6 92.8 90.8 -0.81 -1.17 -1.77 -1.07
46 0.257 -25.3 6.6 11.2 -16.6 362.3 147.2 80.6 91.4 89.9 -0.88 -1.16 -1.7 -1.14
47 0.272 -27.9 6.6 13.8 -16.8 366.5 146.5 79.7 90 88.9 -0.86 -1.15 -1.65 -1.19
48 0.286 -30.3 7 16.7 -16.8 375 145.8 78.7 88.7 87.9 -0.78 -1.14 -1.63 -1.21
49 0.3 -33.5 5.9 17.7 -14.5 386.1 145.2 77.8 87.4 87 -0.68 -1.16 -1.65 -1.18
50 0.315 -38.8 2.3 15.2 -9.6 400.3 144.7 76.8 86 86 -0.62 -1.18 -1.69 -1.12
51 0.329 -45.1 -2.3 11.2 -3.8 418.8 144.2 75.9 84.6 85.1 -0.63 -1.2 -1.75 -1.05
52 0.343 -45.4 -0.1 14.6 2.2 441 143.7 74.9 83.1 84.3 -0.7 -1.23 -1.79 -1
53 0.358 -53.5 -5 12.2 8.7 465.8 143.1 73.8 81.7 83.5 -0.8 -1.29 -1.79 -0.98
54 0.372 -58.8 -6.2 14.7 16.5 493.7 142.4 72.7 80.2 82.7 -0.91 -1.39 -1.76 -0.97
55 0.386 -64.8 -7.9 16.6 26.8 523.9 141.6 71.6 78.8 81.9 -1.1 -1.53 -1.66 -0.94
56 0.4 -71.2 -10.4 16.5 40.1 552.6 140.6 70.2 77.5 81.2 -1.42 -1.72 -1.51 -0.88
57 0.415 -77.3 -12.5 16.1 54.8 576.8 139.2 68.7 76.3 80.5 -1.91 -1.93 -1.32 -0.79
58 0.429 -82.7 -12.4 18.3 68.1 595.8 137.4 67.1 75.3 79.9 -2.52 -2.14 -1.11 -0.66
59 0.443 -87 -10 23.6 79.6 608.6 135.1 65.2 74.5 79.4 -3.2 -2.35 -0.9 -0.48
60 0.458 -89.7 -6.4 29.5 90.8 612.1 132.2 63.2 73.8 79.1 -3.94 -2.55 -0.67 -0.27
61 0.472 -89.8 -2.2 34.4 101.5 602.3 128.6 61.1 73.4 78.9 -4.71 -2.74 -0.43 -0.05
62 0.486 -86.7 2.3 37.3 110.4 576.1 124.5 58.7 73.1 79 -5.44 -2.94 -0.14 0.18
63 0.501 -79.7 6.5 37.2 115.6 530.3 119.7 56.2 73.1 79.2 -6.13 -3.13 0.19 0.41
64 0.515 -68.6 10.1 33.6 114.5 463 114.4 53.6 73.4 79.7 -6.79 -3.28 0.56 0.64
65 0.529 -54.3 12.5 27.5 105.2 377.3 108.6 50.9 74.1 80.3 -7.36 -3.36 0.97 0.86
66 0.543 -38.8 13.3 20.7 88.2 282.1 102.4 48.1 75 81.1 -7.7 -3.33 1.4 1.07
67 0.558 -24.2 12.5 15.2 65.7 190.1 96 45.4 76.4 82 -7.65 -3.18 1.86 1.22
68 0.572 -12.3 10.6 11.9 41.4 110.8 89.8 42.9 78.1 83.1 -7.08 -2.88 2.31 1.27
69 0.586 -3.6 6.8 9.3 18.4 44.4 84.4 40.7 80.2 84.1 -5.92 -2.46 2.73 1.19
70 0.601 1.4 3.6 9 0 0 80.1 38.9 82.5 85 -4.2 -1.91 3.1 1.02
71 0.615 1.4 4.6 10.4 0 0 77.5 37.6 85.2 85.8 -2.11 -1.25 3.43 0.81
72 0.629 1.4 5.7 12.3 0 0 76.7 36.8 88.2 86.3 0.04 -0.49 3.68 0.61
73 0.644 1.3 6.4 13.6 0 0 77.6 36.8 91.3 86.8 1.97 0.35 3.85 0.47
74 0.658 1.1 6.3 13.4 0 0 79.9 37.4 94.5 87.1 3.51 1.24 3.9 0.4
75 0.672 0.9 5.5 11.8 0 0 83.3 38.8 97.7 87.4 4.63 2.11 3.82 0.41
76 0.686 0.7 4.3 9.4 0 0 87.5 40.9 100.7 87.8 5.39 2.92 3.61 0.48
77 0.701 0.6 3 6.8 0 0 92.1 43.6 103.6 88.2 5.9 3.65 3.28 0.59
78 0.715 0.5 1.8 4.2 0 0 97.1 46.8 106.1 88.8 6.24 4.26 2.88 0.71
79 0.729 0.5 0.6 2 0 0 102.4 50.6 108.3 89.4 6.48 4.76 2.47 0.81
80 0.744 0.5 -0.5 0.4 0 0 107.8 54.6 110.1 90.1 6.64 5.15 2.08 0.85
81 0.758 0.5 -1.5 -0.7 0 0 113.3 59 111.7 90.8 6.75 5.45 1.74 0.82
82 0.772 0.6 -2.2 -1.4 0 0 118.8 63.6 113 91.4 6.86 5.66 1.43 0.74
83 0.787 0.6 -2.7 -1.7 0 0 124.5 68.3 114 92 6.98 5.81 1.14 0.63
84 0.801 0.7 -3.1 -2.1 0 0 130.3 73.1 114.9 92.5 7.07 5.91 0.84 0.53
85 0.815 0.8 -3.6 -3 0 0 136.1 78 115.4 92.9 7.09 5.98 0.51 0.45
86 0.829 0.8 -4.3 -4.5 0 0 141.9 82.9 115.7 93.2 7.04 6.04 0.16 0.38
87 0.844 0.7 -5.6 -6.7 0 0 147.6 87.9 115.7 93.5 6.99 6.04 -0.2 0.35
88 0.858 0.6 -7.4 -9.4 0 0 153.3 92.8 115.4 93.8 6.93 5.93 -0.54 0.36
89 0.872 0.4 -9.7 -12.8 0 0 159 97.6 114.8 94.1 6.74 5.63 -0.81 0.41
90 0.887 0.1 -12.3 -16.4 0 0 164.4 102 114 94.4 6.25 5.08 -0.98 0.47
91 0.901 -0.2 -14.5 -19 0 0 169.2 105.9 113.2 94.9 5.36 4.24 -1.01 0.52
92 0.915 -0.4 -15.9 -19.7 0 0 173.2 109 112.4 95.3 4.1 3.14 -0.89 0.57
93 0.93 -0.5 -15.9 -18.6 0 0 175.9 111 111.7 95.8 2.59 1.88 -0.69 0.63
94 0.944 -0.6 -14.5 -15.7 0 0 177.4 112 111.3 96.3 0.94 0.58 -0.48 0.71
95 0.958 -0.5 -11.7 -11.5 0 0 177.5 112 110.9 96.9 -0.78 -0.57 -0.3 0.79
96 0.972 -0.3 -8.2 -6.7 0 0 176.1 111.1 110.8 97.6 -2.45 -1.47 -0.2 0.81
97 0.987 0 -4.9 -2.9 0 0 173.5 109.6 110.6 98.3 -3.9 -2.08 -0.16 0.76
"""


def from_workbook(path: str | Path) -> str:
    """:data:`TABLE` recomputed from the Excel transcription of Winter's Appendix A."""
    from exo_bench.models.gait.normative import _by_frame, _sheets

    sheets = _sheets(Path(path))
    by_sheet = {}
    for prefix in sorted({s for s, _ in _SOURCE.values()}):
        rows = next(v for k, v in sheets.items() if k.startswith(prefix))
        by_sheet[prefix] = _by_frame(rows, {k: c for k, (s, c) in _SOURCE.items() if s == prefix})
    t0 = by_sheet["A3"][HEEL_CONTACT]["t"]
    lines = []
    for f in range(HEEL_CONTACT, NEXT_HEEL_CONTACT + 1):
        v = {k: by_sheet[s][f][k] for k, (s, _) in _SOURCE.items()}
        v["t"] -= t0
        lines.append(" ".join([str(f)] + [f"{v[k]:.6g}" for k in COLUMNS[1:]]))
    return "\n".join(lines) + "\n"


def table() -> dict[str, np.ndarray]:
    """The columns of :data:`TABLE` by name, one value per frame (70 frames, both heel contacts included)."""
    a = np.loadtxt(io.StringIO(TABLE), ndmin=2)
    return {k: a[:, i] for i, k in enumerate(COLUMNS)}


def joint_powers(tab: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Winter's joint powers (W) per frame: ``moment x (omega_distal - omega_proximal)``."""
    tab = table() if tab is None else tab
    return {j: tab[m] * (tab[wd] - tab[wp]) for j, (m, wd, wp) in JOINTS.items()}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m exo_bench.bench.studies.stride.winter Winter_Appendix_data.xlsx", file=sys.stderr)
        return 2
    text = from_workbook(argv[0])
    print(text, end="")
    same = text == TABLE
    print("matches the stored TABLE" if same else "DIFFERS from the stored TABLE", file=sys.stderr)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
