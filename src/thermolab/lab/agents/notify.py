"""E-mail to the teachers when a remote rig goes out of service or comes back.

The standard library's ``smtplib`` and ``email``: one plain-text message per
change, sent from a thread of its own so that a slow or absent mail server
never delays the lab's sweep. Configured by ``thermolab serve --smtp
HOST:PORT --alert-to ADDRESS`` (no SMTP: no e-mail; the teachers' pages
show the fault either way).
"""

from __future__ import annotations

import logging
import smtplib
import threading
from dataclasses import dataclass
from email.message import EmailMessage

__all__ = ["Mailer"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class Mailer:
    """Sends the lab's alerts.

    Attributes
    ----------
    host : str
    port : int
    recipients : tuple of str
    sender : str
    lab_title : str
    """

    host: str
    port: int
    recipients: tuple[str, ...]
    sender: str = "thermolab@localhost"
    lab_title: str = "ThermoLab"

    def __call__(self, rig_id: str, what: str) -> None:
        """Tell the recipients about rig ``rig_id`` (in the background)."""
        message = EmailMessage()
        message["From"] = self.sender
        message["To"] = ", ".join(self.recipients)
        message["Subject"] = f"[{self.lab_title}] rig {rig_id}: {what}"[:200]
        message.set_content(
            f"Rig {rig_id} of {self.lab_title}: {what}.\n\n"
            "The lab takes a remote rig out of service while its host is offline, silent, "
            "faulted or reading outside its safe range, and puts it back by itself when the "
            "host is healthy again. The rig hosts' page lists every host's last contact, "
            "version and fault.\n"
        )
        threading.Thread(target=self._send, args=(message,), daemon=True).start()

    def _send(self, message: EmailMessage) -> None:
        try:
            with smtplib.SMTP(self.host, self.port, timeout=10) as smtp:
                smtp.send_message(message)
        except (OSError, smtplib.SMTPException) as exc:
            log.warning("could not send the alert %r: %s", message["Subject"], exc)
