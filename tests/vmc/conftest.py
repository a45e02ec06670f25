"""The VMC tests drive the avatars' fixtures (the humanoids of ../shared/data/avatars and the CMU walk)."""
from avatar.conftest import rigged, walk  # noqa: F401  (pytest finds fixtures by name in this module)
