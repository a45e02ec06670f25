"""Live 3D faces (Algorithm 2 of the avateering paper): MediaPipe FaceLandmarker's landmarks on the
canonical face mesh, aligned to the frontal template, textured by the camera, anchored at the chin, with
caricatures."""
from .align import Similarity, align
from .caricature import NAMES as MORPH_NAMES
from .caricature import PRESETS, morph_targets
from .reconstruct import Anchor, FaceFrame, reconstruct
from .template import FaceTemplate, load_template

__all__ = ["Anchor", "FaceFrame", "FaceTemplate", "MORPH_NAMES", "PRESETS", "Similarity", "align",
           "load_template", "morph_targets", "reconstruct"]
