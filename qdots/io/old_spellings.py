"""The spellings of files written by qdots 0.1, read as today's: files written by 0.1 keep loading.

0.1 spelled "centre" the American way in the values and keys it wrote. The file readers
(`qdots.io.experiment_file` for experiment and sweep files, `qdots.io.checkpoint` for state files)
pass what they read through `current_experiment` or `current_force` first, so an old file means
what it meant:

==============================================  ============================================
written by 0.1                                  read as
==============================================  ============================================
``deposition.protocol = "center"``              ``deposition.protocol = "centre"``
force ``type = "CenterGravity"``                ``type = "CentreGravity"``
its key ``center = [x, y]``                     ``centre = [x, y]``
==============================================  ============================================

This is data translation only: the Python API takes today's names alone (``Deposition(protocol=
"center")`` is an `labrig.validate.InputError` listing the allowed values).
"""

from __future__ import annotations

#: Old ``deposition.protocol`` values -> today's.
PROTOCOLS = {"center": "centre"}
#: Old force types -> (today's type, {old parameter key: today's}).
FORCES = {"CenterGravity": ("CentreGravity", {"center": "centre"})}


def current_force(spec):
    """A force table (``Force.to_dict()`` output, as read from a file) in today's spelling.

    A table of an old force type gets today's type and parameter keys (a new copy; an old key whose
    new spelling is there too is left as it is, for the force reader to refuse); anything else,
    including a table that is not a dict, is returned as it is, for the force reader to judge.
    """
    if not isinstance(spec, dict) or not isinstance(spec.get("type"), str) or spec["type"] not in FORCES:
        return spec
    name, keys = FORCES[spec["type"]]
    renamed = {old: new for old, new in keys.items() if new not in spec}
    return {"type": name, **{renamed.get(key, key): value for key, value in spec.items() if key != "type"}}


def current_experiment(data):
    """Parsed experiment-file data (nested dicts) in today's spelling: a new copy if anything was old.

    Only values and keys of `PROTOCOLS` and `FORCES` change; anything else, including data of the
    wrong shape, is returned as it is, for the experiment reader to judge.
    """
    if not isinstance(data, dict):
        return data
    data = dict(data)
    deposition = data.get("deposition")
    if isinstance(deposition, dict) and isinstance(deposition.get("protocol"), str) \
            and deposition["protocol"] in PROTOCOLS:
        data["deposition"] = {**deposition, "protocol": PROTOCOLS[deposition["protocol"]]}
    if isinstance(data.get("forces"), list):
        data["forces"] = [current_force(spec) for spec in data["forces"]]
    return data
