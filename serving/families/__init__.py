"""Model families the predictor serves (pysindy style: :mod:`.base` plus one file per family).

:data:`FAMILIES` maps a model's ``model_kind`` metadata to its family class.
"""

from serving.families.base import ModelFamily
from serving.families.cnn import CNNFamily
from serving.families.gbm import GBMFamily

#: ``model_kind`` metadata -> family.
FAMILIES: dict[str, type[ModelFamily]] = {f.model_kind: f for f in (CNNFamily, GBMFamily)}

__all__ = ["FAMILIES", "CNNFamily", "GBMFamily", "ModelFamily"]
