"""doorloc: locate a wooden door in a milling cell from one camera image.

Packages follow the flow of the product:

- :mod:`doorloc.calib`   camera models, calibration files, checkerboard and cell calibration
- :mod:`doorloc.vision`  image -> door pose (x_mm, z_mm, yaw_deg, thickness_mm) or a refusal
- :mod:`doorloc.recipes` door recipes, hinge paths, targets moved by the pose, RAPID exports
- :mod:`doorloc.sim`     renderer of doors and boards with known truth, and the model check
- :mod:`doorloc.app`     command line, HTTP service and batch runner (thin shells)

Shared small types live in :mod:`doorloc.pose` (door pose and the door->cell transform) and
:mod:`doorloc.cell` (the cell file: camera, extrinsics, fixture, envelope, default door).
"""

__version__ = "0.1.0"
