"""Helpers of the command's tests."""

import pytest

from sb3_maddpg.__main__ import main


def fails_with(argv: list[str], capsys: pytest.CaptureFixture) -> str:
    """Run the command, which must end with exit status 2 and one line on stderr, no traceback; return that line."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err
