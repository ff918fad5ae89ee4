"""What the suite writes and how: provenance and atomic writes (``provenance``), what a command may
write over (``files``), the shape of every JSON read back (``json_shape``), publishing a run's reports
under the reports folder's lock, with the names the suite's own reports take (``publish``), how a
command ends early: interrupts and failed solves (``interrupts``), the equations pages
(``equation_pages``, ``latex_document``), rerun recordings (``recording``) and figures (``figures/``).
Nothing here knows a study: the studies above call it."""
