"""The VMC protocol (OSC over UDP): avatar poses out to VSeeFace, Warudo, XR Animator and other performers."""
