"""Deep Linking 2.0: a teacher picks lab items in the LMS's activity picker.

The items a teacher can place are one extension point,
:class:`LinkableItems`: providers (callables) each list items of one kind.
The lab registers rigs and guide pages; assignments register per course
(:meth:`LinkableItems.register_course`: a teacher picks an assignment of the
course the LMS launched them in). An item's ``target`` (``rig:<id>``,
``guide:<rig>/<section>``, ``assignment:<id>``) travels in
the content item's ``custom`` parameters and comes back in every launch of
it, where :func:`target_path` turns it into the page to open.

A deep-linking request is kept in the database (:mod:`.handoffs`: any web
worker can finish it) for 30 minutes, bound to the teacher who launched it;
the answer is a JWT signed with the tool's key, posted back by the browser to
the platform's return URL, and ends the request.
"""

from __future__ import annotations

import re
import secrets
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from thermolab.errors import InvalidParameterError, NotFoundError
from thermolab.lab.db.lti_models import HandoffKind
from thermolab.lab.lti.claims import CLAIM, DEEP_LINKING_RESPONSE, LTI_VERSION
from thermolab.lab.lti.handoffs import Handoff, Handoffs
from thermolab.lab.lti.keys import ToolKeys
from thermolab.lab.lti.platforms import PlatformInfo

__all__ = [
    "TARGET_PARAMETER",
    "DeepLinkRequests",
    "LinkItem",
    "LinkableItems",
    "PendingDeepLink",
    "target_path",
]

TARGET_PARAMETER = "thermolab_target"
# A rig id or a guide section in a target (what the page's own routes accept).
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
# An assignment's number in a target.
_ID = re.compile(r"[1-9][0-9]{0,17}")
_LIFETIME = timedelta(minutes=30)


@dataclass(frozen=True, slots=True)
class LinkItem:
    """Something a teacher can place in an LMS course."""

    kind: str
    target: str
    title: str
    rig: str | None = None


Provider = Callable[[], Sequence[LinkItem]]
CourseProvider = Callable[[str], Sequence[LinkItem]]


class LinkableItems:
    """The registry of linkable kinds (rigs, guide pages, and later assignments)."""

    def __init__(self) -> None:
        self._providers: list[Provider] = []
        self._course_providers: list[CourseProvider] = []

    def register(self, provider: Provider) -> None:
        """Add a provider of items (called each time the list is shown)."""
        self._providers.append(provider)

    def register_course(self, provider: CourseProvider) -> None:
        """Add a provider of one course's items (called with the lab course's name)."""
        self._course_providers.append(provider)

    def items(self, course: str | None = None) -> list[LinkItem]:
        """Every item, provider by provider; a course's own items only when ``course`` is given."""
        found = [item for provider in self._providers for item in provider()]
        if course is not None:
            found += [item for provider in self._course_providers for item in provider(course)]
        return found

    def find(self, target: str, course: str | None = None) -> LinkItem:
        """The item of ``target`` (among the items of ``course``).

        Raises
        ------
        NotFoundError
        """
        for item in self.items(course):
            if item.target == target:
                return item
        raise NotFoundError(f"nothing to link is called {target!r}")


def target_path(target: object) -> str:
    """The browser page (``/#/...``) a launched target opens; the lobby when unknown.

    Examples
    --------
    >>> target_path("rig:twin")
    '/#/rig/twin'
    >>> target_path("guide:twin/theory")
    '/#/rig/twin?guide=theory'
    >>> target_path("assignment:7")
    '/#/assignments/7'
    >>> target_path(None)
    '/#/'
    """
    if isinstance(target, str):
        kind, _, rest = target.partition(":")
        if kind == "rig" and _NAME.fullmatch(rest):
            return f"/#/rig/{rest}"
        rig, _, section = rest.partition("/")
        if kind == "guide" and _NAME.fullmatch(rig) and _NAME.fullmatch(section):
            return f"/#/rig/{rig}?guide={section}"
        if kind == "assignment" and _ID.fullmatch(rest):
            return f"/#/assignments/{int(rest)}"
    return "/#/"


@dataclass(frozen=True, slots=True)
class PendingDeepLink:
    """A deep-linking request waiting for the teacher's choice."""

    user_id: int
    platform: PlatformInfo
    deployment_id: str
    settings: dict[str, Any]
    expires: datetime
    course: str | None = None


def _pending(found: Handoff | None, user_id: int) -> PendingDeepLink:
    if found is None or found.user_id != user_id:
        raise NotFoundError("no such deep-linking request (it may have expired)")
    return PendingDeepLink(
        found.user_id,
        found.platform,
        str(found.data["deployment_id"]),
        dict(found.data["settings"]),
        found.expires,
        found.data.get("course"),
    )


class DeepLinkRequests:
    """Pending deep-linking requests (rows of :class:`.Handoffs`), and the signed answer to one."""

    def __init__(self, handoffs: Handoffs, keys: ToolKeys, items: LinkableItems) -> None:
        self._handoffs = handoffs
        self._keys = keys
        self._items = items

    def open(
        self,
        user_id: int,
        platform: PlatformInfo,
        deployment_id: str,
        settings: dict[str, Any],
        course: str | None = None,
    ) -> str:
        """Keep a request (from the LMS course that fills lab ``course``); return its id."""
        if not isinstance(settings.get("deep_link_return_url"), str):
            raise InvalidParameterError("the deep-linking request has no return URL")
        data = {"deployment_id": deployment_id, "settings": settings, "course": course}
        return self._handoffs.put(HandoffKind.DEEP_LINK, user_id, platform.id, data, _LIFETIME)

    def get(self, key: str, user_id: int) -> PendingDeepLink:
        """A pending request of this teacher.

        Raises
        ------
        NotFoundError
        """
        return _pending(self._handoffs.peek(HandoffKind.DEEP_LINK, key), user_id)

    def items(self, pending: PendingDeepLink) -> list[LinkItem]:
        """What the teacher of ``pending`` can choose (their LMS course's assignments too)."""
        return self._items.items(pending.course)

    def answer(
        self, key: str, user_id: int, targets: list[str], launch_url: str
    ) -> tuple[str, str]:
        """Sign the answer with the chosen items; return (return URL, JWT). Used once.

        Raises
        ------
        NotFoundError
            An unknown, used or expired request, or an unknown item.
        InvalidParameterError
            More than one item where the platform accepts one.
        """
        pending = self.get(key, user_id)
        chosen = [self._items.find(t, pending.course) for t in targets]
        if len(chosen) > 1 and pending.settings.get("accept_multiple") is False:
            raise InvalidParameterError("the LMS accepts one item here: choose one")
        # Used once, on whichever worker answers first.
        _pending(self._handoffs.take(HandoffKind.DEEP_LINK, key), user_id)
        # Shown as the platform accepts it: in its frame if it may, else in a window.
        shown = pending.settings.get("accept_presentation_document_targets") or ["iframe"]
        presentation: dict[str, Any] = (
            {"iframe": {}} if "iframe" in shown else {"window": {"targetName": "thermolab"}}
        )
        now = int(time.time())
        claims: dict[str, Any] = {
            "iss": pending.platform.client_id,
            "aud": pending.platform.issuer,
            "iat": now,
            "exp": now + 300,
            "nonce": secrets.token_urlsafe(16),
            CLAIM["deployment_id"]: pending.deployment_id,
            CLAIM["message_type"]: DEEP_LINKING_RESPONSE,
            CLAIM["version"]: LTI_VERSION,
            CLAIM["dl_content_items"]: [
                {
                    "type": "ltiResourceLink",
                    "title": item.title,
                    "url": launch_url,
                    "custom": {TARGET_PARAMETER: item.target},
                    **presentation,
                }
                for item in chosen
            ],
        }
        if "data" in pending.settings:
            claims[CLAIM["dl_data"]] = pending.settings["data"]
        return str(pending.settings["deep_link_return_url"]), self._keys.sign(claims)
