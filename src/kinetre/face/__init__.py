"""Live 3D faces (Algorithm 2 of the avateering paper): MediaPipe Face Mesh landmarks on the canonical
face mesh, aligned to the frontal template, textured by the camera, anchored at the chin, with caricatures."""
from ..lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "Similarity": ".align", "align": ".align", "MORPH_NAMES": ".caricature:NAMES", "PRESETS": ".caricature",
    "morph_targets": ".caricature", "Anchor": ".reconstruct", "FaceFrame": ".reconstruct",
    "reconstruct": ".reconstruct", "FaceTemplate": ".template", "load_template": ".template"})

__all__ = ["Anchor", "FaceFrame", "FaceTemplate", "MORPH_NAMES", "PRESETS", "Similarity", "align",
           "load_template", "morph_targets", "reconstruct"]
