"""Physics proxies: the mesh as kinematic spheres that follow the deformation (SPEC §4)."""
