"""Model check: from a measured data set, what the cell model gets wrong, its cause, the extended model, the gain.

Above :mod:`doorloc.vision` and :mod:`doorloc.sim` (it uses both); nothing below imports it. The one entry
point is :func:`check_model`.
"""

from doorloc.modelcheck.catalogue import CATALOGUE, EFFECT_NAMES
from doorloc.modelcheck.check import CheckOptions, ModelCheckReport, check_model
from doorloc.modelcheck.dataset import DatasetError

__all__ = ["CATALOGUE", "EFFECT_NAMES", "CheckOptions", "ModelCheckReport", "check_model", "DatasetError"]
