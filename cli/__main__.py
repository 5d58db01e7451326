"""``python -m dancedata.cli``: the same as the ``dancedata`` command."""

from dancedata.cli.main import run

run()
