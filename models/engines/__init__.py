"""The peer engines and the files they read: the generated URDF and the Pinocchio backend, the MJCF and the
MuJoCo backend, the Drake backend, and the joint coordinates their forces are reported in. A new engine's
model export and backend belong here."""
