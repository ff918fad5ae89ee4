"""Forward dynamics in time: ``simulate`` with its checked arguments and budget, the controls (prescribed,
posture holding, external forces), scipy's implicit integrators with an analytic Jacobian, and smooth ground
contact (numpy and CasADi). A new integrator or contact model belongs here."""
