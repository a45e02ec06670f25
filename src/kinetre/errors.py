"""Errors Kinetre raises on bad input: each names the file or argument and the problem."""


class KinetreError(Exception):
    """Base class: the command line prints the message on one line and exits with status 2."""


class BadMeshError(KinetreError):
    """A mesh file is missing, unreadable, empty, a point cloud, non-finite or of zero area."""


class BadGraphError(KinetreError):
    """A deformation graph cannot be built with the requested parameters."""


class BadSkeletonError(KinetreError):
    """A skeleton frame has the wrong shape, unknown joints or an unknown subset name."""


class AttachError(KinetreError):
    """Nothing of the skeleton lies near the mesh, so nothing can be possessed."""


class BadMotionError(KinetreError):
    """A motion file (BVH, recorded take, video) is corrupt or holds no usable motion."""


class BadScanError(KinetreError):
    """RGB-D frames or intrinsics are missing, mismatched or unusable."""


class ExportError(KinetreError):
    """An export target cannot be written."""


class BadFaceError(KinetreError):
    """A face image, video or landmark file is unreadable, holds no face, or has the wrong landmarks."""


class BadAvatarError(KinetreError):
    """An avatar file is not a rigged humanoid glTF/VRM, or its bones cannot be mapped to a body."""


class BadModelError(KinetreError):
    """A tracking model file is missing, unknown, or not byte-identical to the published one."""


class BadSettingsError(KinetreError):
    """A setting (an API argument or the command-line option behind it) that does not fit the input."""
