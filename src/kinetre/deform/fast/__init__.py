"""The fast path of the solver (`SolverSettings.method="pcg"`): one numba call per frame.

- `gauss_newton.py`: the frame: warm start, jump test and the damped Gauss-Newton loop;
- `energy.py`: E and its gradient (the kernel of `deform/energy.py`'s definitions);
- `hessian.py`: the Gauss-Newton matrix H as an operator, its node and bridge blocks;
- `coordinate_split.py`: K, the pose-independent part of H per coordinate, and its block factor;
- `preconditioner.py`: the preconditioners built from that factor and the node blocks;
- `coarse_space.py`: the two-level coarse space of region-affine motions;
- `cg.py`: truncated preconditioned conjugate gradients for one step;
- `live_stop.py`: a live solve's stop, read between steps.
"""
