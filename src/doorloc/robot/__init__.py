"""Robot model: kinematics, reach, deflection and the work window of the milling robot (no images here)."""
