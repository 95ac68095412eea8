# shellcheck shell=bash
# Sourced by .ci/run: replay the Dockerfile outside a container (scripts/ci/container_check.py): the
# image's install from the lock into a clean virtual environment, `doorloc --version`, a locate of the
# bundled image, and the image's CMD until its HEALTHCHECK passes. A failure stops CI.
python3 scripts/ci/container_check.py
