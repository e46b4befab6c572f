"""`python -m backend.labelling.cli`: import recordings into the labelling workspace.

import-urfd [--dir DIR] [--only fall-01 ...]        URFD keypoints + official labels (idempotent)
import-openpose DIR --name NAME [--depth-dir D]     a directory of OpenPose JSON files
import-export FILE [--format json|coco|csv]         a file written by Vigil's export
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from backend.db import make_engine, make_session_factory, transaction
from backend.labelling.errors import LabellingError
from backend.settings import Settings
from vigil.classes import TransportMode


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m backend.labelling.cli")
    commands = parser.add_subparsers(dest="command", required=True)
    urfd = commands.add_parser("import-urfd", help="import URFD (idempotent)")
    urfd.add_argument("--dir", type=Path, default=None, help="URFD directory (VIGIL_URFD_DIR)")
    urfd.add_argument("--only", nargs="*", default=None, help="sequence names, e.g. fall-01")
    urfd.add_argument(
        "--no-labels", action="store_true", help="recordings only, no official labels"
    )
    openpose = commands.add_parser("import-openpose", help="import OpenPose JSON files")
    openpose.add_argument("directory", type=Path)
    openpose.add_argument("--name", required=True)
    openpose.add_argument("--mode", choices=[m.value for m in TransportMode], default="walking")
    openpose.add_argument("--fps", type=float, default=30.0)
    openpose.add_argument("--depth-dir", type=Path, default=None)
    openpose.add_argument("--depth-metres-per-unit", type=float, default=0.001)
    exported = commands.add_parser("import-export", help="import a Vigil export file")
    exported.add_argument("file", type=Path)
    exported.add_argument("--format", choices=["json", "coco", "csv"], default="json")
    exported.add_argument("--name", default=None, help="new video name (json, coco)")
    args = parser.parse_args(argv)

    settings = Settings()
    engine = make_engine(settings.database_url)
    try:
        with transaction(make_session_factory(engine)) as session:
            print(run(session, args, settings))
    except LabellingError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except FileNotFoundError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    finally:
        engine.dispose()
    return 0


def run(session, args, settings: Settings) -> str:
    if args.command == "import-urfd":
        from backend.labelling.importers.urfd import import_urfd

        report = import_urfd(
            session, args.dir or settings.urfd_dir, args.only, labels=not args.no_labels
        )
        return (
            f"URFD: {len(report.created)} videos imported with {report.segments} segments, "
            f"{len(report.skipped)} already there"
        )
    if args.command == "import-openpose":
        from backend.labelling.importers.openpose import import_openpose_dir

        if not args.directory.is_dir():
            raise LabellingError(f"directory: {args.directory} is not a directory")
        video = import_openpose_dir(
            session,
            args.directory,
            args.name,
            mode=TransportMode(args.mode),
            fps=args.fps,
            depth_dir=args.depth_dir,
            depth_metres_per_unit=args.depth_metres_per_unit,
        )
        return f"video {video.name}: {video.frame_count} frames"
    from backend.labelling import exchange

    if not args.file.is_file():
        raise LabellingError(f"file: {args.file} does not exist")
    text = args.file.read_text()
    if args.format == "csv":
        placed = exchange.import_csv(session, text)
        return "labels imported: " + ", ".join(
            f"{name}: {p.created} added, {p.already_there} already there"
            for name, p in placed.items()
        )
    importer = exchange.import_json if args.format == "json" else exchange.import_coco
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise LabellingError(f"file: not JSON ({error.msg})") from error
    video = importer(session, document, args.name).video
    return f"video {video.name}: {video.frame_count} frames"


if __name__ == "__main__":
    sys.exit(main())
