"""Routes of the runs: START and END on a rig, listings, one run, its CSV and JSON exports."""

from __future__ import annotations

from fastapi import APIRouter, status
from fastapi.responses import JSONResponse, StreamingResponse

from thermolab.lab.http.deps import (
    AUTHENTICATED,
    LabDep,
    RigId,
    RigQuery,
    RunId,
    UserDep,
    UserQuery,
    documented_errors,
)
from thermolab.lab.http.schemas import RunIn, RunOut
from thermolab.lab.runs import samples_csv

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


@router.post(
    "/rigs/{rig_id}/runs",
    response_model=RunOut,
    status_code=status.HTTP_201_CREATED,
    tags=["runs"],
    summary="START a run",
    responses=documented_errors(403, 404, 409, 422),
)
def start_run(rig_id: RigId, body: RunIn, who: UserDep, lab: LabDep) -> RunOut:
    """Start sampling the rig you control, with a signal or a manual set point and the
    identification methods to run live (change the set point with PUT .../input).
    """
    lab.config.rig(rig_id)  # an unknown rig is a 404 that names the lab's rigs
    return RunOut.of(lab.runs.start(rig_id, who, body.request()))


@router.post(
    "/rigs/{rig_id}/runs/current/stop",
    response_model=RunOut,
    tags=["runs"],
    summary="END the current run",
    responses=documented_errors(403, 404, 409),
)
def stop_run(rig_id: RigId, who: UserDep, lab: LabDep) -> RunOut:
    """END: stop after the current sample and compute the final estimates (controller or
    teacher). Returns at once; the run's status changes when it has ended.
    """
    lab.config.rig(rig_id)
    return RunOut.of(lab.runs.stop(rig_id, who))


@router.get(
    "/runs",
    response_model=list[RunOut],
    tags=["runs"],
    summary="Runs",
    responses=documented_errors(403, 404, 422),
)
def list_runs(
    who: UserDep,
    lab: LabDep,
    rig: RigQuery = None,
    user: UserQuery = None,
) -> list[RunOut]:
    """Runs, newest first: your own, or everyone's for a teacher (``user`` narrows it to one
    user; a student naming someone else gets 403, a teacher naming nobody known 404).
    """
    return [RunOut.of(run) for run in lab.runs.list(who, rig, user=user)]


@router.get(
    "/runs/{run_id}",
    response_model=RunOut,
    tags=["runs"],
    summary="One run",
    responses=documented_errors(403, 404),
)
def get_run(run_id: RunId, who: UserDep, lab: LabDep) -> RunOut:
    """A run with each method's latest (or final) estimate."""
    return RunOut.of(lab.runs.get(run_id, who))


@router.get(
    "/runs/{run_id}/samples.csv",
    tags=["runs"],
    summary="The run's samples as CSV",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/csv": {}}}, **documented_errors(403, 404)},
)
def run_samples_csv(run_id: RunId, who: UserDep, lab: LabDep) -> StreamingResponse:
    """Columns ``t,u,y`` first, then every other channel of the run by name (``k``,
    ``t_read``, ``jitter``, ``lateness``, and any a rig adds): the file feeds straight
    into ``thermolab identify`` (format: :mod:`thermolab.records`).
    """
    channels, rows = lab.runs.record_rows(run_id, who)
    return StreamingResponse(
        samples_csv(channels, rows),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="run-{run_id}.csv"'},
    )


@router.get(
    "/runs/{run_id}/export.json",
    tags=["runs"],
    summary="The run, its samples and every method's results as JSON",
    responses=documented_errors(403, 404),
)
def run_export(run_id: RunId, who: UserDep, lab: LabDep) -> JSONResponse:
    """Everything stored about a run: settings, samples, trajectories, final estimates."""
    exported = lab.runs.export(run_id, who)
    exported["run"] = RunOut.of(exported["run"]).model_dump(mode="json", by_alias=True)
    return JSONResponse(
        exported,
        headers={"Content-Disposition": f'attachment; filename="run-{run_id}.json"'},
    )
