"""Where the daemon's estimates go: the ``--publish`` links, the autopilot link where
configured, the JSON lines, and the alerts raised on them.

:class:`EstimateOutlet` keeps the latest estimate and whether the link is stale (the estimate
goes out marked stale then), sends NAMED_VALUE_FLOAT and BATTERY_STATUS
(:mod:`estimator.mavlink.publish`) at the configured rate or with every estimate (rate 0),
the 1 Hz HEARTBEAT, the JSON lines at their own rate, and the margin and pack-label alerts
as STATUSTEXT. Times are the event loop's clock (s); the estimates carry the autopilot's.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import replace

from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink import publish
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.json_output import JsonOutput
from estimator.mavlink.link import MavlinkLink
from estimator.mavlink.margin_alerts import MarginAlerts
from estimator.mavlink.pack_alerts import PackLabelAlert

log = logging.getLogger("uav_energy.service")


class EstimateOutlet:
    """The daemon's outputs for one run (the links are opened and closed by the service;
    :meth:`use_pack` before the first estimate)."""

    alerts: MarginAlerts
    pack_alert: PackLabelAlert
    full_usable_wh: float

    def __init__(self, config: ServiceConfig) -> None:
        self.config = config
        self.autopilot: MavlinkLink | None = None  # the autopilot link, once open
        self.outputs: list[MavlinkLink] = []  # the --publish links
        self.json = JsonOutput(config.json)
        self.latest: Estimate | None = None
        self.stale = False
        self._last_json_s = -1e9

    def use_pack(self, pipeline: Pipeline) -> None:
        """The alerts and BATTERY_STATUS scale for ``pipeline``'s pack:
        ``battery_remaining`` and the margins are shares of a full pack's usable energy."""
        cfg = self.config
        self.full_usable_wh = float(pipeline.pack.usable_energy_wh(1.0))
        per_pct_wh = self.full_usable_wh / 100.0
        self.alerts = MarginAlerts(
            cfg.warning_margin_pct * per_pct_wh,
            cfg.critical_margin_pct * per_pct_wh,
            cfg.hysteresis_pct * per_pct_wh,
        )
        self.pack_alert = PackLabelAlert(pipeline.pack.spec.capacity_ah)

    def current(self) -> Estimate | None:
        """The latest estimate, marked stale while the link is."""
        if self.latest is not None and self.stale and not self.latest.stale:
            return replace(self.latest, stale=True)
        return self.latest

    def deliver(self, estimate: Estimate, now_s: float) -> None:
        """A new estimate: keep it for the publish loop, send it and its alerts now where
        configured."""
        self.latest = estimate
        if (alert := self.alerts.update(estimate)) is not None:
            log.warning("%s", alert.text)
            self.statustext(alert.severity, alert.text, self.config.statustext_to_autopilot)
        if (alert := self.pack_alert.update(estimate)) is not None:
            log.warning("%s", alert.text)
            self.statustext(alert.severity, alert.text)
        if self.config.publish_rate_hz == 0:
            self.publish(estimate)
        if self.config.json and (
            self.config.json_rate_hz == 0
            or now_s - self._last_json_s >= 1.0 / self.config.json_rate_hz
        ):
            self._last_json_s = now_s
            self.json.write(estimate)

    def mark_stale(self) -> None:
        """The link went silent: the estimate goes out marked stale (at once when published
        with every estimate)."""
        self.stale = True
        if self.config.publish_rate_hz == 0 and (estimate := self.current()) is not None:
            self.publish(estimate)

    def statustext(self, severity: int, text: str, to_autopilot: bool = False) -> None:
        """A STATUSTEXT on the ``--publish`` links (and the autopilot's when
        ``to_autopilot``)."""
        for link in self._links(to_autopilot):
            link.send(publish.statustext(link, severity, text))

    def publish(self, estimate: Estimate) -> None:
        """NAMED_VALUE_FLOAT and BATTERY_STATUS of ``estimate`` on the configured links."""
        cfg = self.config
        for link in self._links(cfg.values_to_autopilot):
            for msg in publish.named_values(link, estimate):
                link.send(msg)
            if link is not self.autopilot or cfg.battery_status_to_autopilot:
                link.send(
                    publish.battery_status(link, estimate, cfg.battery_id, self.full_usable_wh)
                )

    def heartbeat(self) -> None:
        """Our HEARTBEAT on the ``--publish`` links (and the autopilot's where configured)."""
        estimate = self.current()
        for link in self._links(self.config.heartbeat_to_autopilot):
            link.send(publish.heartbeat(link, estimate))

    async def publish_loop(self) -> None:
        """The latest estimate at ``publish_rate_hz`` (nothing when it is 0: sent with each)."""
        rate_hz = self.config.publish_rate_hz
        if rate_hz == 0:
            return
        while True:
            await asyncio.sleep(1.0 / rate_hz)
            if (estimate := self.current()) is not None:
                self.publish(estimate)

    def _links(self, to_autopilot: bool) -> list[MavlinkLink]:
        """The ``--publish`` links, and the autopilot link when ``to_autopilot``."""
        if to_autopilot and self.autopilot is not None:
            return [*self.outputs, self.autopilot]
        return list(self.outputs)
