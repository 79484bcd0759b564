"""Part 0 of the README's command block runs as written and gives meaningful results (see readme_block); its
``inscal demo --quick`` leaves its output for tests/cli/test_demo_html.py (see demo_share)."""

import demo_share
import pytest
from readme_block import run_part


@pytest.mark.slow
def test_readme_block_part_0(tmp_path, fork_servers, tmp_path_factory):
    run_part(0, tmp_path, fork_servers, demo_share.shared_dir(tmp_path_factory))
