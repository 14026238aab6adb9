"""``sensact learn``: one module per learner, registered in the thesis's chapter order, which ``--help`` keeps."""

from sensact.cli.learn import bootstrap, em, car  # noqa: F401, I001  (chapter 3, 4, 5)
