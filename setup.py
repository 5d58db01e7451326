"""The package list, found rather than hand-kept (a hand-kept list once left out two packages and
broke every wheel install): every folder with an ``__init__.py`` under ``dancedata/``, plus the
Typer layer in ``cli/`` and the store schemas in ``schemas/``, installed under the one
``dancedata`` namespace (``package-dir`` in pyproject.toml maps the folders). Everything else
about the project is in pyproject.toml."""

from setuptools import find_packages, setup


def _under(folder: str, package: str) -> list[str]:
    """``package`` and every subpackage found below ``folder``, named under ``package``."""
    return [package, *(f"{package}.{name}" for name in find_packages(folder))]


setup(
    packages=[
        *_under("dancedata", "dancedata"),
        *_under("cli", "dancedata.cli"),
        *_under("schemas", "dancedata.schemas"),
    ]
)
