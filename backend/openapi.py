"""`python -m backend.openapi` prints the OpenAPI document the frontend client is typed from."""

import sys

from backend.cli import main

if __name__ == "__main__":
    sys.exit(main(["openapi"]))
