"""Scenes: the schema, loading and validation of scene files (:mod:`.loading`; the linear
scenes without contact: :mod:`.linear`) and parameter sampling (:mod:`.sampling`)."""

from rbbench._compat import deprecated_names
from rbbench.scene.linear import LINEAR_PHYSICS  # registers the linear scenes' schema
from rbbench.scene.loading import (
    PROBLEMS_DIR,
    Scene,
    SceneError,
    find_scene,
    load_scene,
    parse_override,
    validate,
)
from rbbench.scene.sampling import parameter_set
from rbbench.scene.schema import Parameter

__all__ = ["LINEAR_PHYSICS", "PROBLEMS_DIR", "Parameter", "Scene", "SceneError", "find_scene",
           "load_scene", "parameter_set", "parse_override", "validate"]


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)
