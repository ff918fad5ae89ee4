"""The studies the suite runs and reports: scenes (a mechanism, a motion, the methods and outputs, in
TOML: ``scenes``, ``scene_motion``; one scene's run: ``scene_run``), a study along one motion against the
50-digit reference (``study``), the loads beside Winter's walking (``plausibility``), the errata of the
paper's formulas (``errata``), numerical stability and forward dynamics (``stability/``), the size of
the composed equations (``equations_size``), the predicted step (``step/``) and stride (``stride/``),
and their typed options (``options``). A new study goes here, as one module or one folder."""
