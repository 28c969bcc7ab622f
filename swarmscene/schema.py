"""Moved: ``swarmscene.schema`` is :mod:`swarmscene.tools.schema` since 0.7.0 (the application's wings,
issue #35). This name, ``python -m swarmscene.schema`` included, works until 0.9.0 with a warning."""

import sys
import warnings

from .tools import schema as _moved

OLD, NEW = "swarmscene.schema", "swarmscene.tools.schema"
if __name__ == "__main__":
    print(f"swarmscene: python -m {OLD} is python -m {NEW} now; the old name works until 0.9.0", file=sys.stderr)
    _moved.main()
else:  # the old import name is the moved module itself
    warnings.warn(f"{OLD} moved to {NEW}; the old name works until 0.9.0", FutureWarning, stacklevel=2)
    sys.modules[__name__] = _moved
