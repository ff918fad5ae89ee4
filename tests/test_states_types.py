"""States are real numbers, read by name where they carry names (issue 34: W8, W9, U8).

``as_states`` (models/states/states.py) is the edge every method's checked call goes through; these tests
call it through ``prepare(...).inverse_dynamics`` as a user does, and check the answers against
Pinocchio within the error model where the input is accepted."""

from decimal import Decimal
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest
from conftest import assert_forces_agree
from hypothesis import given, settings
from hypothesis import strategies as st

from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5
from exo_bench.models.states.states import coordinate_names

MECH = exo5(3)
NAMES = coordinate_names(MECH)
MODEL = prepare(MECH, "newton-euler")


def _states(samples=2, seed=3):
    return random_states(MECH, samples, seed)


NOT_NUMBERS = st.one_of(
    st.text(min_size=0, max_size=12).map(lambda s: f" {s}1_0.5e0 "),  # numpy would parse these as numbers
    st.sampled_from(["1", "nan", "1e3", " 2 ", "0x10", "inf"]),
    st.binary(min_size=1, max_size=4),
    st.decimals(allow_nan=False, allow_infinity=False, places=3),
    st.fractions(),
    st.complex_numbers(allow_nan=False, allow_infinity=False),
    st.none(),
)


@pytest.mark.case("W8", "U8")
@settings(max_examples=60, deadline=None)
@given(bad=NOT_NUMBERS, field=st.sampled_from(["q", "qd", "qdd"]), sample=st.integers(0, 1), column=st.integers(0, 14))
def test_an_entry_that_is_not_a_real_number_is_refused_naming_it(bad, field, sample, column):
    """A string (even one numpy would parse, such as "  1_0.5e0  "), bytes, a Decimal, a Fraction, a complex
    number or None in a list of states is refused, naming the field, the sample and the coordinate."""
    q, qd, qdd = _states()
    states = {"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}
    states[field][sample][column] = bad
    with pytest.raises(
        ValueError,
        match=f"field '{field}': expected real numbers, got .* at sample {sample}, coordinate {NAMES[column]}",
    ):
        MODEL.inverse_dynamics(states["q"], states["qd"], states["qdd"])


@pytest.mark.case("W8")
@pytest.mark.parametrize(
    "row",
    [["1.5"] * 15, [b"1"] * 15, [Decimal("1.5")] * 15, [Fraction(3, 2)] * 15],
    ids=["str", "bytes", "Decimal", "Fraction"],
)
def test_a_whole_row_of_another_type_is_refused(row):
    """A one-sample list made entirely of str, bytes, Decimal or Fraction is refused, naming its first coordinate."""
    q, qd, qdd = _states(1)
    with pytest.raises(ValueError, match=f"field 'q': expected real numbers, got .* at coordinate {NAMES[0]}"):
        MODEL.inverse_dynamics(row, qd[0], qdd[0])


@pytest.mark.case("U8")
def test_ragged_rows_of_arrays_and_none_are_named():
    """Ragged rows given as ndarrays get the ragged-rows message; None is reported as None, not as "nan"."""
    q, qd, qdd = _states()
    with pytest.raises(ValueError, match="ragged rows: .*row 0 with 15 and row 1 with 14"):
        MODEL.inverse_dynamics([q[0], q[1][:-1]], qd, qdd)
    with pytest.raises(ValueError, match=r"got None \(NoneType\) at sample 1, coordinate l1"):
        rows = qd.tolist()
        rows[1][10] = None
        MODEL.inverse_dynamics(q, rows, qdd)


@pytest.mark.case("W9")
@settings(max_examples=20, deadline=None)
@given(perm=st.permutations(range(15)))
def test_a_dataframe_with_the_coordinate_names_is_read_by_name(perm):
    """A DataFrame (or a Series for one sample) whose columns are the coordinate names is read by name, in
    any column order: the forces are those of the states, within the error model."""
    q, qd, qdd = _states()
    order = [NAMES[i] for i in perm]
    frames = [pd.DataFrame(a, columns=NAMES)[order] for a in (q, qd, qdd)]
    ref = prepare(MECH, "pinocchio").inverse_dynamics(q, qd, qdd)
    assert_forces_agree(MODEL.inverse_dynamics(*frames), ref, MECH, q, qd, qdd)
    series = [pd.Series(a[0], index=NAMES)[order] for a in (q, qd, qdd)]
    assert_forces_agree(MODEL.inverse_dynamics(*series)[None], ref[:1], MECH, q[:1], qd[:1], qdd[:1])


@pytest.mark.case("W9")
@pytest.mark.parametrize(
    "columns",
    [
        [f"x{i}" for i in range(15)],
        [*NAMES[:-1], "l6"],
        [*NAMES[:-1], NAMES[0]],
        list(range(1, 16)),
    ],
    ids=["other-names", "one-unknown", "duplicate", "numbers-from-1"],
)
def test_a_dataframe_with_other_columns_is_refused_naming_them(columns):
    """A DataFrame whose columns are neither the coordinate names nor numbered 0..dof-1 is refused, naming the
    missing and unexpected columns."""
    q, qd, qdd = _states()
    with pytest.raises(
        ValueError, match="field 'q': expected columns named phi1..l5 .* got .*(missing|unexpected|duplicate)"
    ):
        MODEL.inverse_dynamics(pd.DataFrame(q, columns=columns), qd, qdd)


@pytest.mark.case("W9")
def test_a_masked_entry_is_refused_and_an_unmasked_array_is_read():
    """A masked array with a masked entry is refused, naming the entry; one with nothing masked is read as
    its data."""
    q, qd, qdd = _states()
    mask = np.zeros(q.shape, bool)
    mask[1, 7] = True
    with pytest.raises(
        ValueError, match=f"field 'qd': expected numbers, got a masked entry at sample 1, coordinate {NAMES[7]}"
    ):
        MODEL.inverse_dynamics(q, np.ma.masked_array(qd, mask=mask), qdd)
    got = MODEL.inverse_dynamics(np.ma.masked_array(q), qd, qdd)
    assert np.array_equal(got, MODEL.inverse_dynamics(q, qd, qdd))
