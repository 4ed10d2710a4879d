// Why the panels are locked for this user now ("" when they may use them).

/**
 * @param {{role: string, queuePosition: number | null} | null} access  this user's access (null: not known yet)
 * @param {string | undefined} state  the rig's state
 * @returns {string}
 */
export function lockReason(access, state) {
  if (!access) return "Connecting…";
  if (state === "out_of_service") return "This rig is out of service.";
  if (state === "fault") return "The rig reports a fault; the controls are locked.";
  if (access.role === "controller") return "";
  return access.role === "queued" || access.queuePosition
    ? `You are number ${access.queuePosition} in the queue; the controls unlock when your turn comes.`
    : "You are watching: the controls are read-only. Ask for control to use them.";
}
