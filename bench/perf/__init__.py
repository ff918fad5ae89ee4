"""The benchmark suite's library (the benchmarks themselves are bench/test_*.py): what a sweep measures
(``profiles``) and its rows (``rows``), the
peers outside this package (``peers``), the derivative routes the derivatives benchmark times
(``derivative_routes``), where the limit is (``roofline``), the cost model's calibration
(``calibration``), and the reports made from a run (``reports/``)."""
