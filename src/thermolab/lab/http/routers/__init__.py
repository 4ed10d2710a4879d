"""One router per resource of the HTTP API, all under ``/api``.

Every route but ``POST /api/session`` needs a logged-in user (401 otherwise).
"""

from fastapi import APIRouter

from thermolab.lab.http.routers import control, methods, rigs, runs, session, users

__all__ = ["api_router"]

api_router = APIRouter(prefix="/api")
for _resource in (session, rigs, runs, methods, users, control):
    api_router.include_router(_resource.router)
