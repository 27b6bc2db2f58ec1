"""Camera models: the contract, the registry and each lens model."""

from camkit.lens.base import MODELS, CameraModel, FieldOfView, get_model, model_from_params, register_model
from camkit.lens.pinhole import Pinhole

__all__ = [
    "MODELS",
    "CameraModel",
    "FieldOfView",
    "Pinhole",
    "get_model",
    "model_from_params",
    "register_model",
]
