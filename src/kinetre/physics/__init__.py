"""Physics proxies: the mesh as kinematic spheres that follow the deformation (KinÊtre paper,
"Physics-based Interactions")."""
