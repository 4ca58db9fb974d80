"""The spellings of files written by earlier versions, read as today's: old files keep loading.

0.1 spelled "centre" the American way in the values and keys it wrote, up to 0.2 the van der Waals
force carried the numerical knobs of its pair list and its own sticking speed, and the ``[engine]`` table
held the settings of both engines (the one chosen by its ``kind`` read its own). The file readers
(`qdots.io.experiment_file` for experiment and sweep files, `qdots.io.checkpoint` for state files)
pass what they read through `current_experiment`, or `current_force`, `current_numerics` and
`current_engine`, first, so an old file means what it meant:

==============================================  ============================================
written by 0.1                                  read as
==============================================  ============================================
``deposition.protocol = "center"``              ``deposition.protocol = "centre"``
force ``type = "CenterGravity"``                ``type = "CentreGravity"``
its key ``center = [x, y]``                     ``centre = [x, y]``
``VanDerWaals`` keys ``skin``, ``near_gap``,        ``[engine]`` keys ``pair_skin``, ``near_gap``,
``far_interval`` (0.2)                          ``far_interval`` (numerics, not physics)
``VanDerWaals`` key ``sticking_speed`` (0.2)    nothing when it equals the collision rule's
                                                (the one sticking speed); else the proxy
                                                offset it gave, ``offset = b``
``[engine]`` keys of an engine other than its   checked against their declaration, then
``kind`` (0.2: ``max_events`` of a Chipmunk     dropped: that engine never read them
run, ``substeps`` of an event run, ...)
==============================================  ============================================

The last rule holds for every file, as one key switches a table to another engine (a sweep's
``engine.kind`` axis, ``qdots run --engine``): the other engine's keys stay checked and unread.

This is data translation only: the Python API takes today's names alone (``Deposition(protocol=
"center")`` is an `labrig.validate.InputError` listing the allowed values).
"""

from __future__ import annotations

from labrig.validate import InputError, typed

from ..forces.vdw import thesis_offset

#: Old ``deposition.protocol`` values -> today's.
PROTOCOLS = {"center": "centre"}
#: Old force types -> (today's type, {old parameter key: today's}).
FORCES = {"CenterGravity": ("CentreGravity", {"center": "centre"})}
#: Numerical knobs a VanDerWaals table of 0.2 held -> their ``[engine]`` names (`qdots.engine.PairScheme`).
VDW_NUMERICS = {"skin": "pair_skin", "near_gap": "near_gap", "far_interval": "far_interval"}


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


def current_numerics(forces, engine, sticking_speed):
    """``(forces, engine)`` with the numerical knobs of 0.2's VanDerWaals tables moved into the engine table and
    their own sticking speed read as today's (see the module's table); new copies when anything moved.

    Parameters
    ----------
    forces : list
        Force tables (after `current_force`).
    engine : dict or None
        The engine settings table (None: none given).
    sticking_speed : float
        The collision rule's sticking speed, px/s.

    Raises
    ------
    labrig.validate.InputError
        When a knob moved from a force table differs from the engine table's own value, or from another
        force table's.
    """
    if not isinstance(forces, list):
        return forces, engine
    moved, out = {}, []
    for k, spec in enumerate(forces):
        if not (isinstance(spec, dict) and spec.get("type") == "VanDerWaals"
                and (set(VDW_NUMERICS) | {"sticking_speed"}) & set(spec)):
            out.append(spec)
            continue
        spec = dict(spec)
        for old, new in VDW_NUMERICS.items():
            if old in spec:
                value = spec.pop(old)
                value = None if value is False else value  # "unset" in a file
                if moved.get(new, value) != value:
                    raise InputError(f"forces[{k}].{old} = {value!r} differs from another force's {old}: it is now "
                                     f"one engine setting, engine.{new}")
                moved[new] = value
        if "sticking_speed" in spec:
            own = spec.pop("sticking_speed")
            if own != sticking_speed and "offset" not in spec:
                spec["offset"] = thesis_offset(_number(spec, "r0", 15.0), _number(spec, "min_gap", 0.1), own)
        out.append(spec)
    if not moved:
        return out, engine
    engine = dict(engine) if isinstance(engine, dict) else {}
    for key, value in moved.items():
        if key in engine and engine[key] != value:
            raise InputError(f"the VanDerWaals force's {key} = {value!r} differs from engine.{key} = {engine[key]!r}: "
                             f"set it once, in the engine table")
        engine[key] = value
    return out, engine


def _number(spec: dict, key: str, default: float) -> float:
    value = spec.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"VanDerWaals.{key} must be a number, got {value!r}")
    return float(value)


def current_engine(table):
    """An ``[engine]`` table in today's spelling: the keys that only engines other than its ``kind`` take are
    checked against their declarations and dropped (a new copy when any is). A table that is not a dict, or of
    an unknown kind, is returned as it is, for the engine reader to judge.

    Raises
    ------
    labrig.validate.InputError
        Naming ``engine.KEY`` when a dropped key's value is not one its engine allows.
    """
    from ..engine import ENGINES

    kind = table.get("kind", "chipmunk") if isinstance(table, dict) else None
    if not isinstance(kind, str) or kind not in ENGINES:
        return table
    own = ENGINES[kind].PARAMS
    others = {key: cls.PARAMS[key] for cls in ENGINES.values() for key in cls.PARAMS if key not in own}
    dropped = [key for key in table if key in others]
    for key in dropped:
        param = others[key]
        param.check(f"engine.{key}", typed(f"engine.{key}", table[key], param.file_kind))
    return {key: value for key, value in table.items() if key not in dropped} if dropped else table


def current_experiment(data):
    """Parsed experiment-file data (nested dicts) in today's spelling: a new copy if anything was old.

    Only values and keys of `PROTOCOLS` and `FORCES`, the moved knobs (`current_numerics`) and the keys of
    other engines (`current_engine`) change; anything else, including data of the wrong shape, is returned as
    it is, for the experiment reader to judge.
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
        rule = data.get("restitution")
        sticking = rule.get("sticking_speed", 1.0) if isinstance(rule, dict) else 1.0
        forces, engine = current_numerics(data["forces"], data.get("engine"), sticking)
        data["forces"] = forces
        if engine is not None:
            data["engine"] = engine
    if "engine" in data:
        data["engine"] = current_engine(data["engine"])
    return data
