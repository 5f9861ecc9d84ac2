"""The ``workbench`` command: a thin shell over functions the tests call directly."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..datasets import DataUnavailableError
from .config import ConfigError, load_config
from .evaluate import evaluate, format_table


def _write_json(path: str, payload: dict) -> None:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(payload, indent=2) + "\n")
    tmp.replace(out)  # never leave a half-written result


def _cmd_evaluate(args) -> int:
    cfg = load_config(args.config)
    if args.jobs is not None:
        cfg = type(cfg)(**{**cfg.__dict__, "n_jobs": args.jobs})
    result = evaluate(cfg)
    print(format_table(result))
    if args.json:
        _write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="workbench", description="Base boosting workbench.")
    sub = parser.add_subparsers(dest="command", required=True)
    ev = sub.add_parser("evaluate", help="fit a config's model on the training rows and score "
                        "prior and model on the test rows")
    ev.add_argument("config", help="experiment config (TOML), e.g. experiments/paper_main_body.toml")
    ev.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ev.add_argument("--jobs", type=int, default=None, metavar="N",
                    help="targets fitted in parallel (overrides the config's n_jobs)")
    ev.set_defaults(func=_cmd_evaluate)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ConfigError, DataUnavailableError) as exc:
        print(f"workbench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
