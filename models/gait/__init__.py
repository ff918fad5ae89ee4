"""Motions given as data: the paper's gait (eq. 26) and other prescribed motions with analytic derivatives,
seeded random states, and the normative level walking (Winter) that the gait is fitted to and the loads are
compared with."""
