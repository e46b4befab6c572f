# Robot agent image: the domain package and the agent only (no web or database stack).
FROM python:3.11-slim-bookworm
ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1
RUN apt-get update && apt-get install -y --no-install-recommends libgl1 libglib2.0-0 \
    && rm -rf /var/lib/apt/lists/*
WORKDIR /app
COPY pyproject.toml README.md ./
COPY vigil/ vigil/
COPY robot_agent/ robot_agent/
RUN pip install '.[robot]'
RUN useradd --system --uid 10001 vigil && mkdir -p /app/var && chown vigil /app/var
USER vigil
CMD ["vigil-robot", "--help"]
