"""The live client reads the server's frames: one message, or an array of them in order.

Also: a server whose numbers are below the client's (its clock was set back
across a restart) makes the client count from the server's present again.
"""

from __future__ import annotations

from typing import Any

import pytest

from .test_modules import FAKES, run_js

pytestmark = pytest.mark.browser


def test_a_frame_with_an_array_delivers_each_message_in_order(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        const s0 = sockets[0];
        s0.open();
        s0.msg({ type: 'hello', seq: 10, rig: {}, access: {}, run: null });
        s0.msg([{ type: 'sample', seq: 11, k: 0, t: 0, u: 1, y: 2, run: 7 },
                { type: 'estimate', seq: 12, run: 7, method: 'wlsm', k: 0, K: 1, tau: 2 },
                { type: 'access', access: { role: 'watcher' } },
                { type: 'sample', seq: 12, k: 0, t: 0, u: 1, y: 2, run: 7 },  // seen already
                { type: 'sample', seq: 13, k: 1, t: 1, u: 1, y: 2, run: 7 }]);
        s0.msg({ type: 'sample', seq: 14, k: 2, t: 2, u: 1, y: 2, run: 7 });
        client.stop();
        return { seqs: got.map((m) => m.type + ':' + (m.seq ?? '-')), lastSeq: client.lastSeq };
        """,
    )
    assert r["seqs"] == [
        "hello:10",
        "sample:11",
        "estimate:12",
        "access:-",
        "sample:13",
        "sample:14",
    ]
    assert r["lastSeq"] == 14


def test_a_server_numbering_below_ours_is_followed_from_its_hello(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        sockets[0].open();
        sockets[0].msg({ type: 'hello', seq: 5000, rig: {}, access: {}, run: null });
        sockets[0].msg({ type: 'sample', seq: 5001, k: 0, t: 0, u: 1, y: 2, run: 7 });
        sockets[0].drop();
        advance(60000);
        const s1 = sockets[1];
        s1.open();
        s1.msg({ type: 'hello', seq: 300, rig: {}, access: {}, run: null });  // restarted
        s1.msg({ type: 'sample', seq: 301, k: 1, t: 1, u: 1, y: 2, run: 7 });
        client.stop();
        return { url: s1.url, seqs: got.map((m) => m.type + ':' + m.seq), lastSeq: client.lastSeq };
        """,
    )
    assert r["url"] == "rig-1?since=5001"
    assert r["seqs"] == ["hello:5000", "sample:5001", "hello:300", "sample:301"]
    assert r["lastSeq"] == 301
