"""The thin DDS driver: a ROS 2 node on Cyclone DDS (PyPI ``cyclonedds``) writing CDR bytes.

One :class:`Node` is one DDS participant (domain ``ROS_DOMAIN_ID``) holding one ROS 2 node:
participant USER_DATA ``enclave=/;``, latched writers with Jazzy's ``typehash`` user data, and its
``ros_discovery_info`` sample. Payloads are serialised by :mod:`mapkit.ros2.messages`; this module
only hands the bytes to DDS. Writers announce XCDR1 only, as rmw_fastrtps and rmw_cyclonedds do.
"""

from __future__ import annotations

import threading
from typing import Any

from mapkit.ros2.errors import Ros2Error
from mapkit.ros2.graph import (
    DISCOVERY_TOPIC,
    LATCHED,
    QosSpec,
    dds_topic,
    endpoint_user_data,
    participant_user_data,
)
from mapkit.ros2.messages import PARTICIPANT_ENTITIES_INFO, participant_entities_info_cdr, type_hash

__all__ = ["Node", "Writer"]

INSTALL_HINT = "the ROS 2 bridge needs the ros2 extra: pip install 'mapkit[ros2]'"


def _binding() -> Any:
    try:
        import cyclonedds.core
        import cyclonedds.domain
        import cyclonedds.pub
        import cyclonedds.topic
        import cyclonedds.util
    except ImportError as err:
        raise Ros2Error(f"{INSTALL_HINT} ({err})") from err
    return cyclonedds


def _qos(spec: QosSpec, user_data: bytes = b"") -> Any:
    cdds = _binding()
    P = cdds.core.Policy
    policies = [
        P.Reliability.Reliable(cdds.util.duration(seconds=1))
        if spec.reliable
        else P.Reliability.BestEffort,
        P.Durability.TransientLocal if spec.transient_local else P.Durability.Volatile,
        P.History.KeepLast(spec.depth),
        P.DataRepresentation(use_cdrv0_representation=True),
    ]
    if user_data:
        policies.append(P.Userdata(user_data))
    return cdds.core.Qos(*policies)


class Writer:
    """A ROS 2 publisher: ``write`` takes the CDR bytes of one message (with its header)."""

    def __init__(
        self,
        node: Node,
        topic: str,
        typename: str,
        qos: QosSpec = LATCHED,
        *,
        dds_name: str | None = None,
    ) -> None:
        from mapkit.ros2.dds_types import dds_type

        cdds = _binding()
        self.typename = typename
        self.topic = dds_name or dds_topic(topic, node.namespace)
        self._cls = dds_type(typename, node.distro)
        thash = type_hash(typename, node.distro) if node.distro != "humble" else None
        try:
            self._topic = cdds.topic.Topic(node.participant, self.topic, self._cls)
            self._writer = cdds.pub.DataWriter(
                node.participant, self._topic, qos=_qos(qos, endpoint_user_data(thash))
            )
        except Exception as err:  # cyclonedds raises DDSException for any DDS failure
            raise Ros2Error(f"cannot create the DDS writer for {self.topic}: {err}") from err
        self.gid = self._writer.guid.bytes

    def write(self, cdr: bytes) -> None:
        """Publish one message's serialised bytes (``00 01 00 00`` + XCDR1 body)."""
        sample = object.__new__(self._cls)
        # The binding calls sample.serialize(); hand it the bytes rosbags made (about 100x
        # faster than the binding's own serialiser for a large grid, and the same bytes).
        sample.serialize = lambda **_kw: cdr
        try:
            self._writer.write(sample)
        except Exception as err:
            raise Ros2Error(f"writing {self.topic} failed: {err}") from err


class Node:
    """A DDS participant that ROS 2 tools see as one node.

    Args:
        name: The node's name.
        domain: The ROS 2 domain (``ROS_DOMAIN_ID``).
        namespace: The node's namespace.
        distro: Whose discovery layout to write: ``jazzy`` (type hashes, 16-byte Gid) or
            ``humble`` (no hashes, 24-byte Gid).

    Raises:
        Ros2Error: When the binding is missing or the participant cannot be created.
    """

    def __init__(
        self, name: str, domain: int = 0, namespace: str = "/", distro: str = "jazzy"
    ) -> None:
        cdds = _binding()
        if not 0 <= domain <= 232:
            raise Ros2Error(f"ROS 2 domain must be 0..232, got {domain}")
        self.name, self.namespace, self.distro = name, namespace, distro
        self._lock = threading.Lock()
        try:
            self.participant = cdds.domain.DomainParticipant(
                domain, qos=cdds.core.Qos(cdds.core.Policy.Userdata(participant_user_data()))
            )
        except Exception as err:
            raise Ros2Error(f"cannot join DDS domain {domain}: {err}") from err
        self.writers: dict[str, Writer] = {}
        self._discovery = Writer(
            self, DISCOVERY_TOPIC, PARTICIPANT_ENTITIES_INFO, dds_name=DISCOVERY_TOPIC
        )

    def writer(self, topic: str, typename: str, qos: QosSpec = LATCHED) -> Writer:
        """A writer on a ROS 2 topic (created once; the node's graph entry is updated)."""
        with self._lock:
            if topic not in self.writers:
                self.writers[topic] = Writer(self, topic, typename, qos)
                self._announce()
            return self.writers[topic]

    def _announce(self) -> None:
        gids = [w.gid for w in self.writers.values()]
        self._discovery.write(
            participant_entities_info_cdr(
                self.participant.guid.bytes, self.name, self.namespace, gids, distro=self.distro
            )
        )

    def close(self) -> None:
        """Leave the domain (peers see the node and its topics go)."""
        # The binding deletes a DDS entity (and its children) when its Python object goes.
        self.writers.clear()
        self._discovery = None  # type: ignore[assignment]
        self.participant = None
