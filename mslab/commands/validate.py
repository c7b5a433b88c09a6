"""``mslab validate FILE...``: check scene files without running them.

Prints one line per file: ``FILE: ok (...)`` or ``mslab: error: FILE: KEY: reason``
(on stderr). Exit code 0 when every file is valid, 2 otherwise.
"""

from __future__ import annotations

import sys

from mslab.commands.common import add_common_options, emit_json, say


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "validate",
        help="check scene files without running them",
        description="Check scene files (or built-in names) and report the first "
        "mistake of each as one line FILE: KEY: reason.",
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="scene .toml files or built-in scene names")
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def run(args) -> int:
    from mslab.errors import SceneError
    from mslab.scenes.loader import load_scene
    from mslab.simulate import step_count

    results = []
    for name in args.files:
        try:
            scene = load_scene(name)
        except SceneError as err:
            results.append(
                {"file": name, "ok": False, "key": err.key, "reason": err.reason, "error": str(err)}
            )
            print(f"mslab: error: {str(err).splitlines()[0]}", file=sys.stderr)
            continue
        s = scene.settings
        n_steps = step_count(s.t_end, s.dt)
        results.append({"file": name, "ok": True, **scene.summary(), "steps": n_steps})
        say(
            args,
            f"{name}: ok ({scene.n_particles} particles, {len(scene.spring_kind)} springs, effects: "
            f"{', '.join(scene.effects) or 'none'}; {s.method}, dt = {s.dt:g}, "
            f"{n_steps} steps to {s.t_end:g} s)",
        )
    if args.json:
        emit_json({"files": results, "ok": all(r["ok"] for r in results)})
    return 0 if all(r["ok"] for r in results) else 2
