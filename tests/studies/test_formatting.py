"""studies.formatting.significant: display digits, blanks for missing values."""

from __future__ import annotations

import numpy as np
import pandas as pd

from rbbench.studies.formatting import significant


def test_significant_digits_blanks_and_other_cells():
    df = pd.DataFrame({"a": [1.23456e-4, np.nan, 70.0], "b": ["ok", None, 3]})
    out = significant(df)
    assert out["a"].tolist() == ["0.000123", "", 70.0]
    assert out["b"].tolist() == ["ok", "", 3]
    assert df.loc[0, "a"] == 1.23456e-4  # the table itself is unchanged
