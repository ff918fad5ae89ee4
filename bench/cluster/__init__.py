"""The benchmark sweep and the stability study as tasks on a Dask cluster (``--full``): the tasks a
worker runs (``tasks``), scheduling them and collecting their results (``cluster``), the checkpoints
that let an interrupted sweep run only what is missing (``checkpoints``), every wait bounded
(``waits``), and the two commands built from them (``commands``)."""
