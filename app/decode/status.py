"""The optical sensor's status: whether its values may be used at a given time (head
connected, not too hot, …), from the latest status frame."""

from app.config import StatusCondition


class SensorStatus:
    """The latest value of each status signal, and whether a role may be used at time t."""

    def __init__(self, conditions: tuple[StatusCondition, ...], timeout_s: float) -> None:
        self.conditions = conditions
        self.timeout_s = timeout_s
        self.values: dict[str, float] = {}
        self.t: float | None = None
        # role -> the conditions on it, as (signal name, value it needs)
        self._relevant: dict[str, tuple[tuple[str, float], ...]] = {}
        self._verdicts: dict[str, str | None] = {}  # role -> what the values say, until they change
        self.stale = f"sensor status older than {timeout_s:g} s"

    def applies(self, role: str) -> bool:
        """Whether any condition is on ``role``."""
        return any(role in c.applies_to for c in self.conditions)

    def update(self, t: float, values: dict[str, float]) -> None:
        self.values.update(values)
        self.t = t
        self._verdicts.clear()

    def why_not(self, role: str, t: float) -> str | None:
        """None when every condition on ``role`` holds at time t, else the reason it does not."""
        relevant = self._relevant.get(role)
        if relevant is None:
            relevant = self._relevant[role] = tuple(
                (c.name, c.value) for c in self.conditions if role in c.applies_to
            )
        if not relevant:
            return None
        if self.t is None:
            return "no sensor status yet"
        if abs(t - self.t) > self.timeout_s:
            return self.stale
        verdicts = self._verdicts
        if role not in verdicts:
            verdicts[role] = self._verdict(relevant)
        return verdicts[role]

    def _verdict(self, relevant: tuple[tuple[str, float], ...]) -> str | None:
        for name, needed in relevant:
            value = self.values.get(name)
            if value is None:
                return f"no {name} yet"
            if value != needed:
                return f"{name}={value:g} (needs {needed:g})"
        return None
