"""How the suite itself runs (scripts/run-tests.sh): what keeps it inside CI's ten minutes."""

from __future__ import annotations

import pytest


@pytest.mark.xdist_group("one_worker")
def test_tests_marked_with_one_xdist_group_are_sent_to_one_worker(request):
    """Tests sharing a costly module fixture (a build, a Kennecott model) carry one ``xdist_group`` mark so one
    worker computes it once. pytest 9.2 stored a test's id where pytest-xdist's --dist loadgroup no longer marks
    it (pytest-dev/pytest-xdist#1386): the marks went unheeded without a word, and each worker computed the
    fixture again."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not run on workers with --dist loadgroup")
    assert request.node.nodeid.endswith("@one_worker"), request.node.nodeid
