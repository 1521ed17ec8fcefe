"""The techniques, one folder each (its function and ``Technique`` spec in ``technique.py``), the
spec itself (``spec.py``), the parameters several share (``params.py``) and the registry
(``registry.py``)."""
