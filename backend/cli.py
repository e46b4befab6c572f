"""`vigil-backend`: migrate, seed demo data, serve, dump the OpenAPI."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from backend.settings import REPO_ROOT, Settings


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="vigil-backend")
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("migrate", help="apply database migrations")
    demo = commands.add_parser("seed-demo", help="create demo users and robots (idempotent)")
    demo.add_argument("--robots", type=int, default=3)
    demo.add_argument("--tokens-file", type=Path, default=REPO_ROOT / "var" / "robot_tokens.json")
    demo.add_argument(
        "--passwords-file",
        type=Path,
        default=REPO_ROOT / "var" / "demo_passwords.json",
        help="where the generated demo passwords are kept (mode 600)",
    )
    demo.add_argument(
        "--no-urfd", action="store_true", help="skip importing URFD into the labelling workspace"
    )
    serve = commands.add_parser("serve", help="run the backend")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    commands.add_parser("openapi", help="print the OpenAPI document")
    args = parser.parse_args(argv)
    settings = Settings()

    if args.command == "migrate":
        from backend.migrate import upgrade

        upgrade(settings.database_url)
        print("database is at the newest migration")
    elif args.command == "seed-demo":
        from backend.db import make_engine, make_session_factory, transaction
        from backend.demo import ensure_demo_robots, ensure_demo_users, seed_urfd

        engine = make_engine(settings.database_url)
        with transaction(make_session_factory(engine)) as session:
            credentials = ensure_demo_users(session, args.passwords_file)
            ensure_demo_robots(session, args.robots, args.tokens_file)
        if not args.no_urfd:
            try:
                with transaction(make_session_factory(engine)) as session:
                    report = seed_urfd(session, settings.urfd_dir)
                print(
                    f"URFD in the labelling workspace: {len(report.created)} videos imported, "
                    f"{len(report.skipped)} already there"
                )
            except FileNotFoundError as error:
                print(f"URFD not imported: {error}")
        engine.dispose()
        print(
            "Demo accounts (passwords generated for this machine, kept in "
            f"{args.passwords_file}; change them before real use):"
        )
        for username, password, role in credentials:
            shown = password or "(set before; not changed)"
            print(f"  {role.value:<10} user {username:<10} password {shown}")
        print(f"Robot tokens for {args.robots} simulated robots: {args.tokens_file}")
    elif args.command == "serve":
        import uvicorn

        uvicorn.run("backend.main:app", host=args.host, port=args.port, log_level="info")
    elif args.command == "openapi":
        from backend.main import create_app

        json.dump(create_app(settings).openapi(), sys.stdout, indent=1)
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
