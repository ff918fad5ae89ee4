"""State arrays ``q, qd, qdd`` (and ``tau``): their block order and labels (the form of eqs. 5 and 17), their
conversion at the edge (lists, DataFrames, other dtypes), and their validation: the value checks of
``check=True`` (one compiled pass), what ``check=False`` still checks for memory safety, and the bounds on a
mechanism's fields. A new input check belongs here."""
