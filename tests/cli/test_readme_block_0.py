"""Part 0 of the README's command block runs as written and gives meaningful results (see readme_block)."""

import pytest
from readme_block import run_part


@pytest.mark.slow
def test_readme_block_part_0(tmp_path, fork_servers):
    run_part(0, tmp_path, fork_servers)
