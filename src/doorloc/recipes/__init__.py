"""Door recipes, their database, hinge pocket paths, targets moved by the pose, and RAPID exports."""
