"""`langtraj recipe NAME|FILE --out RUN [--workers W] [--max-steps N]`: the whole training chain, synthesis
to final checkpoint, each step resumed or skipped when done (docs/model.md, 'The recipe').

NAME is a recipe of `configs/recipes/` (`tiny`, `gpu-short`, `base`) looked up from the current folder; FILE is a
recipe YAML anywhere.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "recipe", help="the whole training chain: synth, labels, stages 1, 2, distill, closed loop"
    )
    p.add_argument("recipe", metavar="NAME|FILE", help="tiny, gpu-short, base, or a recipe YAML (configs/recipes/)")
    p.add_argument("--out", required=True, type=Path, help="run folder (corpus, labels, one folder per stage)")
    p.add_argument("--workers", type=int, default=2, help="processes for synthesis and labelling (default 2)")
    p.add_argument("--max-steps", type=int, help="cap every training stage (a smoke run)")
    p.set_defaults(func=run)


def recipe_path(name: str) -> Path:
    """A recipe file given by path, or by name in `configs/recipes/` under the current folder."""
    from langtraj.errors import InputError

    path = Path(name)
    if path.is_file():
        return path
    named = Path("configs") / "recipes" / f"{name}.yaml"
    if named.is_file():
        return named
    raise InputError(f"no recipe file {name!r} and no {named} in the current folder", where="recipe")


def run(args: argparse.Namespace) -> int:
    from langtraj.errors import InputError
    from langtraj.training.recipe import load_recipe, run_recipe

    if args.workers < 1:
        raise InputError(f"must be at least 1, got {args.workers}", where="--workers")
    recipe = load_recipe(recipe_path(args.recipe))
    last = run_recipe(recipe, args.out, workers=args.workers, max_steps=args.max_steps)
    print(f"recipe {recipe.name}: final checkpoint {last}")
    return 0
