"""Camera models: the contract, the registry and each lens model."""

from camkit.lens.base import MODELS, CameraModel, FieldOfView, get_model, model_from_params, register_model
from camkit.lens.brown_conrady import BrownConrady
from camkit.lens.chromatic import LateralChromaticAberration
from camkit.lens.kannala_brandt import KannalaBrandt
from camkit.lens.opencv import from_opencv, from_opencv_fisheye, to_opencv
from camkit.lens.pinhole import Pinhole

__all__ = [
    "MODELS",
    "BrownConrady",
    "CameraModel",
    "FieldOfView",
    "KannalaBrandt",
    "LateralChromaticAberration",
    "Pinhole",
    "from_opencv",
    "from_opencv_fisheye",
    "get_model",
    "model_from_params",
    "register_model",
    "to_opencv",
]
