# doorloc HTTP service. Build: docker build -t doorloc .
# Run:   docker run -p 8000:8000 -v /path/to/cell:/etc/doorloc:ro -v doorloc-data:/var/lib/doorloc doorloc
# The cell file (and the calibration it names) is mounted read-only; the recipe database (SQLite by
# default) lives on a volume. Set DOORLOC_DATABASE_URL for PostgreSQL. The service listens on 0.0.0.0, which
# `doorloc serve` allows only with API keys: create them in the database volume (`doorloc keys create --role
# operator|engineer|metrics NAME`) or pass one engineer key as a secret in DOORLOC_API_KEY; without keys
# the container exits with that sentence. The database on the volume is created on first start (the image's
# own URL, not a typed one); set DOORLOC_ALLOWED_HOSTS to the names clients use (the image allows any, as
# keys are required). TLS: a reverse proxy in front (docs/deploy.md).
# Versions come from the lock (requirements/lock-service-py311.txt, the same versions as CI's lock);
# torch is not in it: the service does not need it.
# No container engine runs on the development machines: scripts/ci/container_check.py (run by .ci/run)
# performs this file's install, CMD and HEALTHCHECK outside a container, so the file cannot silently rot.

# --- build: a virtual environment made from the lock ---
FROM python:3.11-slim-bookworm AS build
ENV VIRTUAL_ENV=/opt/doorloc
WORKDIR /src
COPY requirements/lock-service-py311.txt requirements/
COPY scripts/install-venv scripts/
COPY pyproject.toml README.md ./
COPY src src/
RUN scripts/install-venv "$VIRTUAL_ENV" requirements/lock-service-py311.txt
# locate's numba kernels, compiled into the image (the service would otherwise compile them at every start)
RUN NUMBA_CACHE_DIR="$VIRTUAL_ENV/numba-cache" "$VIRTUAL_ENV/bin/python" -m doorloc.vision.warmup

# --- runtime: the virtual environment only, a non-root user, a health check ---
FROM python:3.11-slim-bookworm
ENV VIRTUAL_ENV=/opt/doorloc
ENV PATH=/opt/doorloc/bin:$PATH \
    PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 \
    DOORLOC_CELL=/etc/doorloc/cell.yaml \
    DOORLOC_DATABASE_URL=sqlite:////var/lib/doorloc/recipes.db \
    OMP_NUM_THREADS=1 \
    NUMBA_CACHE_DIR=/opt/doorloc/numba-cache \
    DOORLOC_CREATE_DATABASE=true \
    DOORLOC_ALLOWED_HOSTS=*
RUN useradd --system --uid 10001 --home-dir /var/lib/doorloc --create-home doorloc
COPY --from=build /opt/doorloc /opt/doorloc
# numba reads its cache only from a folder it may write (it checks): the service user's
COPY --from=build --chown=doorloc /opt/doorloc/numba-cache /opt/doorloc/numba-cache
USER doorloc
WORKDIR /var/lib/doorloc
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s --start-period=20s \
  CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=2).status != 200)"
CMD ["doorloc", "serve", "--host", "0.0.0.0", "--port", "8000", "--workers", "1"]
