"""``sensact learn``: one module per learner, registered in the thesis's chapter order, which ``--help`` keeps:
``bootstrap`` (chapter 3), ``em`` (chapter 4, and every other log kind through the app's registry) and
``velodyne_car`` (chapter 5's ``learn car``)."""

from sensact.cli.learn import bootstrap, em, velodyne_car  # noqa: F401  (chapter 3, 4, 5)
