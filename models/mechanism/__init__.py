"""The mechanism as plain data: a tree of telescopic rods with point masses (``Mechanism``), its presets
(the paper's models, human models from Winter's anthropometry, chains and random trees), reading it from JSON,
and its geometry: mass aggregates (eq. 6), the rod elements, point-mass kinematics and energies, the factored
mass coupling, singular configurations, net joint loads, and the 50-digit virtual-work reference. Nothing here
knows a method."""
