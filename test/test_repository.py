"""The repository speaks for itself: no tracked file points at material users do not have."""
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Paths of the development workspace, which users never get (split so this file passes),
#: and this checkout's own absolute path (a result file that recorded where it ran).
PRIVATE = ('shared/' + 'reference', '/' + 'work/', '../' + 'shared', str(ROOT) + '/')


def test_no_tracked_file_cites_the_private_workspace():
    try:
        listed = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, capture_output=True,
                                check=True).stdout.decode().split('\0')
    except (OSError, subprocess.CalledProcessError):
        pytest.skip('not a git checkout')
    offenders = []
    for name in filter(None, listed):
        path = ROOT / name
        if not path.is_file() or path.suffix in ('.png', '.stl', '.mcap', '.npz'):
            continue
        text = path.read_text(errors='ignore')
        offenders += [f'{name}: {p}' for p in PRIVATE if p in text]
    assert not offenders, offenders
