"""``mslab scenes``: list the built-in scenes; ``mslab scenes NAME`` prints one scene file."""

from __future__ import annotations

from typing import TYPE_CHECKING

from mslab.commands.common import add_common_options, emit_json, say

if TYPE_CHECKING:
    import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab scenes`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "scenes",
        help="list the built-in scenes (or print one scene file)",
        description="List the built-in scenes with their size, effects and run settings.",
    )
    p.add_argument(
        "name", nargs="?", metavar="NAME", help="print this scene's TOML file (a template to copy)"
    )
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def describe(name: str) -> dict:
    """Size, effects and default run settings of a built-in scene."""
    from mslab.scenes.loader import load_scene, scene_path

    summary = load_scene(name).summary()
    del summary["scene"]
    return {"name": name, **summary, "file": str(scene_path(name))}


def run(args: argparse.Namespace) -> int:
    """Run ``mslab scenes`` with the parsed ``args``; return the exit code."""
    from mslab.scenes.loader import scene_names, scene_path

    if args.name:
        path = scene_path(args.name)
        text = path.read_text(encoding="utf-8")
        if args.json:
            emit_json({"name": args.name, "file": str(path), "text": text})
        else:
            print(text, end="")
        return 0
    rows = [describe(name) for name in scene_names()]
    if args.json:
        emit_json({"scenes": rows})
        return 0
    say(
        args,
        f"{'scene':16s} {'dim':>3s} {'particles':>9s} {'springs':>7s}  {'method':16s} {'dt':>7s} "
        f"{'t_end':>6s}  effects / description",
    )
    for r in rows:
        say(
            args,
            f"{r['name']:16s} {r['dim']:3d} {r['n_particles']:9d} {r['n_springs']:7d}  {r['method']:16s} "
            f"{r['dt']:7g} {r['t_end']:6g}  {', '.join(r['effects'])}: {r['description']}",
        )
    say(args, "run one with `mslab run NAME`; copy one with `mslab scenes NAME > my_scene.toml`")
    return 0
