"""Numerical stability of the qdots engine on hard cases (scenes: `qdots.diagnostics.hard_cases`).

Each case asserts: every sampled state is finite; no dot is lost (left the box, or swallowed by
another); no dot crossed a grating line; the settled overlap (dots and walls) is below 5 % of a
radius, and every sampled overlap is below 10 % (plus, with fixed sub-steps, the discrete-contact
bound ``impact_speed * dt / substeps / r``: Chipmunk sees a contact only once the discs overlap).
`qdots.diagnostics.hard_cases` states each case's impact-speed bound and why.

Known failures (measured limits, listed in docs/performance.md) are strict xfails: a change that
fixes one shows up as an unexpected pass. Long cases are marked slow. With the default adaptive
sub-steps the settled bound is `qdots.diagnostics.hard_cases.SETTLED_TOLERANCE` (5 %) and the transient bound
10 %.
"""

import pytest

from qdots.diagnostics.hard_cases import CASES, check


def case_params() -> list:
    """One parameter per case (a list: pytest refuses a generator), slow and known-failure cases marked."""
    params = []
    for case in CASES:
        marks = [pytest.mark.slow] if case.slow else []
        if case.known_failure:
            marks.append(pytest.mark.xfail(strict=True, reason=case.known_failure))
        params.append(pytest.param(case, id=case.name.split(",")[0].replace(" ", "-") + "-" + str(CASES.index(case)),
                                   marks=marks))
    return params


@pytest.mark.parametrize("case", case_params())
def test_hard_case_is_stable(case):
    result = check(case)
    assert not result["warned"] or case.known_failure, f"{case.name}: the engine warned that dots move too fast"
    assert result["finite"], f"{case.name}: NaN or infinite positions/velocities"
    assert not result["lost"], f"{case.name}: a dot left the box or was swallowed by another"
    assert not result["crossed"], f"{case.name}: a dot crossed a grating line"
    assert result["settled"] < result["settled_tolerance"], (
        f"{case.name}: settled overlap {result['settled']:.3%} >= {result['settled_tolerance']:.0%}")
    assert result["overlap"] < result["transient_tolerance"], (
        f"{case.name}: overlap {result['overlap']:.3%} >= {result['transient_tolerance']:.1%} during impacts")



def test_passing_through_walls_is_warned_about_and_adaptive_sub_steps_prevent_it():
    fixed = next(case for case in CASES if case.name.endswith("fixed sub-steps"))
    result = check(fixed)
    assert result["warned"] and (result["lost"] or result["crossed"])
    adaptive = check(next(case for case in CASES if case.name.startswith("head-on at 3000x") and case is not fixed))
    assert not adaptive["warned"] and not adaptive["lost"] and adaptive["overlap"] < 0.1
