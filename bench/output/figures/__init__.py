"""The figures of a scene, in matplotlib's object API: the colours and text sizes every figure and
recording shares (``palette``), the curves of a study (``curves``: net joint moments, rod forces,
differences between methods) and a scene's figure set with the stick figures of its motion
(``scene_figures``: kinogram, overview, trail points). The figures of a study's own report (stability,
step, stride, benchmarks) live beside that report."""
