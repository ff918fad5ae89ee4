"""The reports' writer is the one writer, not a wrapper around it (the guide: one responsibility per file;
bench/output/provenance.py kept ``atomic_write`` and ``atomic_path`` as thin wrappers of
models/files.py, which dropped its ``label`` and ``inputs`` options)."""

from __future__ import annotations

from exo_bench.bench.output import files, provenance
from exo_bench.models import files as encoders


def test_provenance_names_the_one_writer_itself():
    assert provenance.atomic_write is encoders.atomic_write
    assert provenance.atomic_path is encoders.atomic_path


def test_the_output_files_module_keeps_no_copy():
    """bench's files.py writers use models/files.py's own functions (kind_of is imported from there where used)."""
    assert files.replace_atomically is encoders.replace_atomically
    assert not hasattr(files, "kind_of")
