"""The deprecated entry-point group ``swarmscene.policies``: each factory it lists is registered as
a policy for one more release, with a DeprecationWarning pointing to ``swarmscene_register_policies``
(:func:`swarmscene.methods.policy.policies.entry_point_policies`). A name already registered is
skipped with a warning naming both, instead of the old group's crash."""

from __future__ import annotations

import warnings

from swarmscene.methods.policy.policies import entry_point_policies
from swarmscene.plugin import hookimpl


@hookimpl(trylast=True)
def swarmscene_register_policies(register):
    """Register each policy of the older ``swarmscene.policies`` entry-point group; one whose
    name a hook already took is skipped with a warning."""
    for cls in entry_point_policies():
        try:
            register(cls)
        except Exception as exc:  # a duplicate name: the hook's registration wins
            warnings.warn(f"swarmscene: skipping {cls.__doc__}: {exc}", RuntimeWarning, stacklevel=2)
