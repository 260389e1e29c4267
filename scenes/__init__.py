"""The shipped scene files (TOML; schema in sim/SCENES.md), installed as package data ``evedge.scenes``."""
