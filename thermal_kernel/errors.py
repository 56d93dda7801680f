"""The scene's error, below every module that raises it: ``scene.py`` (the reader),
``boundaries/`` (each kind's checks), ``problem.py``, ``neighbours.py``, ``calibrate.py``. Its
own module so that the boundary kinds need not import the scene reader that imports them."""


class SceneError(ValueError):
    """A bad scene file; ``str(e)`` is one line naming the file and the key."""
