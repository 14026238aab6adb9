"""``sensact learn``: one module per learner, registered in the thesis's chapter order, which ``--help`` keeps."""

from sensact.cli.learn import bootstrap, em, velodyne_car  # noqa: F401  (chapter 3, 4, 5)
