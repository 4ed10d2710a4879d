"""The bus that delivers a run's events without ever delaying sampling.

One fan-out machinery: each subscriber has its own bounded queue
(:class:`Subscription`). :meth:`EventBus.publish` only appends to those
queues (a lock and a deque append per subscriber): it never waits for a
consumer, so a slow or blocked subscriber cannot delay the sampling loop. A
subscriber whose queue is full has fallen too far behind: it is disconnected
and marked (``cut`` is true, ``cut_reason`` says why). It still receives the
events already queued, then :class:`~thermolab.errors.SubscriberCutError`. A
server answers by resynchronising the client from a snapshot.

Two ways to consume the same queue:

* :meth:`EventBus.subscribe`: pull (``drain``, iteration) from any thread.
* :meth:`EventBus.subscribe_callback`: a function called on a thread of its
  own, in event order (what the lab service uses to forward events to its
  live stream, which does its own asyncio fan-out to browsers).

When the run is over the bus is closed: consumers receive what is queued and
then the end of the stream. The events themselves are
:mod:`thermolab.runner.events`.
"""

from __future__ import annotations

import itertools
import threading
from collections import deque
from collections.abc import Callable, Iterator

from thermolab.errors import InvalidParameterError, SubscriberCutError
from thermolab.runner.events import Event

__all__ = ["EventBus", "Subscription"]


class Subscription:
    """A subscriber's bounded queue, filled by the publisher and drained by one consumer.

    Created by :meth:`EventBus.subscribe` (consumed by the caller, from any
    thread) or :meth:`EventBus.subscribe_callback` (consumed on a thread of
    its own). The lock is held only for a deque operation, never while a
    consumer runs.

    Examples
    --------
    >>> from thermolab.runner import RunState, StateEvent
    >>> bus = EventBus()
    >>> sub = bus.subscribe(maxsize=8)
    >>> bus.publish(StateEvent(bus.next_seq(), RunState.RUNNING, RunState.IDLE))
    >>> bus.close()
    >>> [event.kind for event in sub]
    ['state']
    """

    def __init__(self, bus: EventBus, name: str, maxsize: int) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise InvalidParameterError(
                f"a subscriber's queue size must be an integer >= 1, got {maxsize!r}"
            )
        self.name = name
        self.maxsize = maxsize
        self._bus = bus
        self._items: deque[Event] = deque()
        self._lock = threading.Lock()
        self._ready = threading.Condition(self._lock)
        self._closed = False
        self._cut_reason: str | None = None

    # -- state visible to the consumer and to the run ----------------------------

    @property
    def cut(self) -> bool:
        """``True`` if the subscriber fell too far behind and was disconnected."""
        return self._cut_reason is not None

    @property
    def cut_reason(self) -> str | None:
        """Why the subscriber was cut, or ``None``."""
        return self._cut_reason

    @property
    def closed(self) -> bool:
        """``True`` once no more events will be queued (end of run, cut or unsubscribed)."""
        return self._closed

    def close(self) -> None:
        """Unsubscribe: no more events are queued; what is queued can still be read."""
        self._bus._remove(self)
        self._finish(None)

    # -- consumer side -------------------------------------------------------------

    def drain(self) -> list[Event]:
        """Return every queued event without waiting (possibly none).

        Raises
        ------
        SubscriberCutError
            If nothing is queued and the subscriber was cut.
        """
        with self._lock:
            events = list(self._items)
            self._items.clear()
            if not events and self._cut_reason is not None:
                raise SubscriberCutError(self._cut_reason)
            return events

    def __iter__(self) -> Iterator[Event]:
        """Yield events until the stream ends (raises if the subscriber is cut)."""
        while True:
            with self._ready:
                while True:
                    event = self._take()
                    if event is not None:
                        break
                    if self._closed:
                        return
                    self._ready.wait()
            yield event

    # -- publisher side ------------------------------------------------------------

    def _put(self, event: Event) -> None:
        with self._lock:
            if self._closed:
                return
            items = self._items
            if len(items) < self.maxsize:
                items.append(event)
                self._ready.notify()
                return
            self._closed = True
            self._cut_reason = (
                f"subscriber {self.name!r} fell {len(items)} events behind "
                f"(its queue holds {self.maxsize}) and was disconnected"
            )
            self._ready.notify()
        self._bus._remove(self)

    def _finish(self, cut_reason: str | None) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if cut_reason is not None:
                self._cut_reason = cut_reason
            self._ready.notify()

    def _take(self) -> Event | None:
        """Pop the next event (lock held); ``None`` if there is none yet.

        Raises
        ------
        SubscriberCutError
            If the queue is empty and the subscriber was cut.
        """
        if self._items:
            return self._items.popleft()
        if self._cut_reason is not None:
            raise SubscriberCutError(self._cut_reason)
        return None

    def __repr__(self) -> str:
        status = "cut" if self.cut else "closed" if self._closed else "open"
        return f"<Subscription {self.name!r} {status} pending={len(self._items)}>"


class _CallbackRunner:
    """Consumes a :class:`Subscription` on a daemon thread, calling a function per event."""

    def __init__(
        self,
        bus: EventBus,
        subscription: Subscription,
        callback: Callable[[Event], object],
        fatal_errors: bool,
    ) -> None:
        self._bus = bus
        self._subscription = subscription
        self._callback = callback
        self._fatal_errors = fatal_errors
        self.thread = threading.Thread(
            target=self._run, name=f"thermolab-subscriber-{subscription.name}", daemon=True
        )

    def _run(self) -> None:
        sub = self._subscription
        try:
            for event in sub:
                self._callback(event)
        except SubscriberCutError:
            return
        except Exception as exc:
            message = f"subscriber {sub.name!r} raised {type(exc).__name__}: {exc}"
            sub.close()
            if self._fatal_errors:
                self._bus._fail(message, exc)


class EventBus:
    """Fan-out of a run's events to any number of bounded subscriber queues.

    Publishing is safe from any thread and never blocks on a consumer.

    Examples
    --------
    >>> from thermolab.runner import RunState, StateEvent
    >>> bus = EventBus()
    >>> fast = bus.subscribe(maxsize=100, name="fast")
    >>> slow = bus.subscribe(maxsize=2, name="slow")
    >>> for _ in range(3):
    ...     bus.publish(StateEvent(bus.next_seq(), RunState.RUNNING, RunState.IDLE))
    >>> len(fast.drain()), slow.cut
    (3, True)
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        # Copy-on-write tuple: publish() iterates it without taking the lock.
        self._queues: tuple[Subscription, ...] = ()
        self._counter = itertools.count()
        self._names = itertools.count(1)
        self._closed = False
        self._failure: tuple[str, BaseException] | None = None

    @property
    def active(self) -> bool:
        """``True`` if any subscriber is connected (publishers may skip building events)."""
        return bool(self._queues)

    @property
    def subscribers(self) -> tuple[Subscription, ...]:
        """The connected subscriptions."""
        return self._queues

    @property
    def closed(self) -> bool:
        """``True`` after :meth:`close`."""
        return self._closed

    @property
    def failure(self) -> tuple[str, BaseException] | None:
        """``(message, exception)`` of a callback subscriber whose error is fatal, or ``None``."""
        return self._failure

    def next_seq(self) -> int:
        """Return the next event number (thread-safe, starts at 0)."""
        return next(self._counter)

    def subscribe(self, *, maxsize: int = 1024, name: str | None = None) -> Subscription:
        """Add a pull subscriber.

        Parameters
        ----------
        maxsize : int, optional
            Events the queue holds; a subscriber that falls further behind is
            cut (default 1024).
        name : str, optional
            For messages (default ``"subscriber-N"``).

        Returns
        -------
        Subscription
            Already closed if the bus is closed.

        Raises
        ------
        InvalidParameterError
            If ``maxsize`` is not an integer >= 1.
        """
        sub = Subscription(self, self._name(name), maxsize)
        self._add(sub)
        return sub

    def subscribe_callback(
        self,
        callback: Callable[[Event], object],
        *,
        maxsize: int = 1024,
        name: str | None = None,
        fatal_errors: bool = True,
    ) -> Subscription:
        """Call ``callback(event)`` for every event, on a daemon thread of its own.

        Parameters
        ----------
        callback : callable
            Called once per event, in order. It may block: only its own queue
            fills up.
        maxsize, name
            As for :meth:`subscribe`.
        fatal_errors : bool, optional
            If ``True`` (default) an exception from ``callback`` is recorded in
            :attr:`failure`, and a run publishing on this bus stops (FAULTED,
            actuator safe). If ``False`` the subscriber is only disconnected.

        Returns
        -------
        Subscription
            The queue the thread consumes (for ``cut``, ``cut_reason``, ``close()``).
        """
        sub = Subscription(self, self._name(name), maxsize)
        runner = _CallbackRunner(self, sub, callback, fatal_errors)
        self._add(sub)
        runner.thread.start()
        return sub

    def publish(self, event: Event) -> None:
        """Queue ``event`` for every subscriber; never waits for a consumer.

        Parameters
        ----------
        event : Event
            The event (numbered with :meth:`next_seq`).
        """
        for queue in self._queues:
            queue._put(event)

    def close(self) -> None:
        """End the stream: subscribers get what is queued, then the end (idempotent)."""
        with self._lock:
            self._closed = True
            queues, self._queues = self._queues, ()
        for queue in queues:
            queue._finish(None)

    # -- internals -------------------------------------------------------------

    def _name(self, name: str | None) -> str:
        return name if name is not None else f"subscriber-{next(self._names)}"

    def _add(self, queue: Subscription) -> None:
        with self._lock:
            if not self._closed:
                self._queues = (*self._queues, queue)
                return
        queue._finish(None)

    def _remove(self, queue: Subscription) -> None:
        with self._lock:
            self._queues = tuple(q for q in self._queues if q is not queue)

    def _fail(self, message: str, exc: BaseException) -> None:
        with self._lock:
            if self._failure is None:
                self._failure = (message, exc)

    def __repr__(self) -> str:
        return f"<EventBus subscribers={len(self._queues)} closed={self._closed}>"
