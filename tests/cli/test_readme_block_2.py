"""Part 2 of the README's command block runs as written and gives meaningful results (see readme_block)."""

import pytest
from readme_block import run_part


@pytest.mark.slow
def test_readme_block_part_2(tmp_path, fork_servers):
    run_part(2, tmp_path, fork_servers)
