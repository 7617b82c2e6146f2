"""The scenes (``*.toml``) and run matrices (``matrices/*.toml``) shipped with rbbench.

Installed as the package data of ``rbbench.problems`` (``pyproject.toml`` maps it to this
directory), in a wheel and in an editable install alike; read through
:mod:`importlib.resources` (:data:`rbbench.scene.loading.PROBLEMS_DIR`).
"""
