# doorloc HTTP service. Build: docker build -t doorloc .
# Run:   docker run -p 8000:8000 -v /path/to/cell:/etc/doorloc:ro -v doorloc-data:/var/lib/doorloc doorloc
# The cell file (and the calibration it names) is mounted read-only; the recipe database (SQLite by
# default) lives on a volume. Set DOORLOC_DATABASE_URL for PostgreSQL and DOORLOC_API_KEY to require a key.
# torch/kornia are an optional extra ("doorloc[torch]") and are not needed by the service.

FROM python:3.11-slim-bookworm AS build
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /src
COPY pyproject.toml README.md ./
COPY src ./src
RUN python -m pip wheel --wheel-dir /wheels ".[postgres]"

FROM python:3.11-slim-bookworm
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 \
    DOORLOC_CELL=/etc/doorloc/cell.yaml \
    DOORLOC_DATABASE_URL=sqlite:////var/lib/doorloc/recipes.db \
    OMP_NUM_THREADS=1
RUN useradd --system --uid 10001 --home-dir /var/lib/doorloc --create-home doorloc
COPY --from=build /wheels /wheels
RUN python -m pip install --no-index --find-links /wheels "doorloc[postgres]" && rm -rf /wheels
USER doorloc
WORKDIR /var/lib/doorloc
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s --start-period=20s \
  CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=2).status != 200)"
CMD ["doorloc", "serve", "--host", "0.0.0.0", "--port", "8000", "--workers", "1"]
