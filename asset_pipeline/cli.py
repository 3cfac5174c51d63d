"""The ``pact`` command line: sample, build, validate, convert, train and evaluate.

Library code lives in the packages; this module only parses arguments, shows
progress and maps failures to exit codes. Commands from the training side
(``tasks``) are imported lazily inside their command functions.
"""

from __future__ import annotations

import logging
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from generator.procedural import CATEGORIES

app = typer.Typer(
    help="Photos of articulated furniture and appliances -> simulation-ready assets and RL tasks.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
console = Console(stderr=True)


@app.callback()
def _root(verbose: bool = typer.Option(False, "--verbose", "-v", help="Debug logging.")) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )


@app.command()
def sample(
    category: str = typer.Option(
        ..., "--category", "-c", help=f"One of: {', '.join(CATEGORIES)}, or 'all'."
    ),
    n: int = typer.Option(1, "--n", min=1, help="How many objects."),
    seed: int = typer.Option(0, "--seed", help="Seed of the first object; object k uses seed + k."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder; one bundle per object."),
    split: str = typer.Option("train", "--split", help="Parameter ranges: train or test."),
) -> None:
    """Sample seeded procedural articulated objects as bundles in OUT/<id>/."""
    from generator.articulated import save_bundle
    from generator.procedural import UnknownCategoryError, object_id, sample_object

    cats = list(CATEGORIES) if category == "all" else [category]
    written = []
    for cat in cats:
        for k in range(n):
            try:
                obj = sample_object(cat, seed + k, split=split)
            except UnknownCategoryError as e:
                console.print(f"[red]error:[/red] {e}")
                raise typer.Exit(2) from e
            d = save_bundle(obj, out / object_id(cat, seed + k, split))
            written.append(d)
    for d in written:
        print(d)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
