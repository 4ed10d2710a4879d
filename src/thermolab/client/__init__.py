"""A Python client of a ThermoLab lab: ``Lab(url, token=...)``.

List rigs, ask for control and wait in the queue (the place reported), set
inputs and read outputs, start runs with the method registry's settings,
follow a run live, and fetch runs as NumPy arrays or pandas DataFrames. A
personal API token (from the user's page in the lab, or ``$THERMOLAB_TOKEN``)
stands in for the password. The client speaks API
:data:`thermolab.api_version.API_VERSION` and refuses a lab of another major
version (or an older minor) with one clear message. It imports nothing of
the lab's server side (a contract in ``pyproject.toml`` checks it).
"""

from thermolab.client.errors import LabRequestError, TurnEndedError
from thermolab.client.lab import ENV_TOKEN, ENV_URL, Lab, print_place
from thermolab.client.live import follow_run
from thermolab.client.runs import RunData
from thermolab.client.turn import Reading, Turn

__all__ = [
    "ENV_TOKEN",
    "ENV_URL",
    "Lab",
    "LabRequestError",
    "Reading",
    "RunData",
    "Turn",
    "TurnEndedError",
    "follow_run",
    "print_place",
]
