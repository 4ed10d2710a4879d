"""One router per resource of the HTTP API, all under ``/api``.

Every route but ``POST /api/session``, ``POST /api/enrol``, ``GET /api/version``,
``GET /api/privacy`` and the LTI launch's (``/api/lti/login``, ``/launch``,
``/continue``, ``/jwks``) and a calendar feed's secret address (``/api/calendar/…``)
needs a logged-in user or an API token (401 otherwise).
"""

from fastapi import APIRouter

from thermolab.lab.http.routers import (
    agents,
    analytics,
    assignments,
    audit,
    booking_tools,
    bookings,
    control,
    course_settings,
    courses,
    grading,
    guide_images,
    guides,
    lti,
    lti_admin,
    me,
    methods,
    people,
    privacy,
    readings,
    rig_settings,
    rigs,
    runs,
    session,
    term,
    tokens,
    users,
    version,
)

__all__ = ["api_router"]

api_router = APIRouter(prefix="/api")
for _resource in (
    session,
    version,
    privacy,
    rigs,
    readings,
    runs,
    methods,
    users,
    tokens,
    control,
    guides,
    guide_images,
    courses,
    rig_settings,
    assignments,
    grading,
    bookings,
    booking_tools,
    analytics,
    lti,
    lti_admin,
    agents,
    course_settings,
    audit,
    me,
    people,
    term,
):
    api_router.include_router(_resource.router)
# A calendar feed's secret address: a calendar application has no login.
api_router.include_router(booking_tools.public_router)
