"""Routes of a user's personal API tokens: ``/api/tokens`` (list, create, revoke)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Response, status

from thermolab.errors import AccessDeniedError
from thermolab.lab.http.deps import AUTHENTICATED, MAX_ROW_ID, LabDep, UserDep, documented_errors
from thermolab.lab.http.script_schemas import NewTokenOut, TokenIn, TokenOut

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


@router.get("/tokens", response_model=list[TokenOut], tags=["tokens"], summary="Your API tokens")
def list_tokens(who: UserDep, lab: LabDep) -> list[TokenOut]:
    """Your personal API tokens, newest first (never their secrets)."""
    return [TokenOut.of(info) for info in lab.tokens.of_user(who)]


@router.post(
    "/tokens",
    response_model=NewTokenOut,
    status_code=status.HTTP_201_CREATED,
    tags=["tokens"],
    summary="Create an API token",
    responses=documented_errors(403, 409, 422),
)
def create_token(body: TokenIn, who: UserDep, lab: LabDep) -> NewTokenOut:
    """Create a token for scripts; the answer's ``token`` is the secret, shown this once.

    Only from a password login (the browser): a token cannot create tokens,
    so a read-only one cannot mint a full one.
    """
    if who.token_id is not None:
        raise AccessDeniedError("an API token cannot create tokens; log in with your password")
    new = lab.tokens.create(who, body.name, read_only=body.read_only, days=body.days)
    return NewTokenOut(token=new.secret, **TokenOut.of(new.info).model_dump())


@router.delete(
    "/tokens/{token_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["tokens"],
    summary="Revoke an API token",
    responses=documented_errors(404),
)
def revoke_token(
    token_id: Annotated[int, Path(ge=1, le=MAX_ROW_ID)], who: UserDep, lab: LabDep
) -> Response:
    """Revoke one of your tokens: refused from the next request on, its live sockets closed."""
    lab.tokens.revoke(who, token_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
