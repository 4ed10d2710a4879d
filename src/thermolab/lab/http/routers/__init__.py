"""One router per resource of the HTTP API, all under ``/api``.

Every route but ``POST /api/session``, ``POST /api/enrol`` and ``GET /api/version``
needs a logged-in user or an API token (401 otherwise).
"""

from fastapi import APIRouter

from thermolab.lab.http.routers import (
    control,
    courses,
    guides,
    methods,
    readings,
    rigs,
    runs,
    session,
    tokens,
    users,
    version,
)

__all__ = ["api_router"]

api_router = APIRouter(prefix="/api")
for _resource in (
    session,
    version,
    rigs,
    readings,
    runs,
    methods,
    users,
    tokens,
    control,
    guides,
    courses,
):
    api_router.include_router(_resource.router)
