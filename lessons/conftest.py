"""pytest in lessons/: the notebooks (nbval); never the student release made by `make lab`."""

collect_ignore = ["student"]
