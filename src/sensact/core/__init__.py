"""Numerics every learner shares; numpy, scipy and numba only.

* ``angles``: angle wrapping (differences wrapped to [-pi, pi));
* ``geometry``: robot families by state space (planar, track), the types the compiled kernels switch on;
* ``pose_models``: the one pose algebra, in sensact's one internal frame (x right, y forward; sec. 2.5.1),
  and the crossing to REP 103 (``from_rep103``, ``to_rep103``);
* ``ekf_smoother``: the E-step's compiled passes (sec. 4.2): EKF, two-filter smoother, pairwise posteriors;
* ``inertial_smoother``: the outdoor robot's E-step: an EKF and RTS smoother over the path, the odometry the
  action, the gyro and GNSS the sensors, the constant parameters in the state;
* ``smallmat``: small dense linear algebra for the compiled per-step loops;
* ``polyfit``, ``recursive`` and ``degree``: weighted polynomial regression, batch (sec. 2.3), recursive with
  forgetting (sec. 3.3.2), and its degree chosen by the data;
* ``changepoint``: sequential change detection on standardized scores;
* ``raycast``: ray casting against prisms and a ground plane, for the simulated lidars.
"""
