"""The models both sides share: the robot's (DH tables, forward kinematics, the terms beyond the
geometry, the robot library) and the tracker's (its noise)."""
