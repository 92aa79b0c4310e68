"""The asyncua side of ``aioadept opcua``: load the OPC Foundation's DI, IA and Robotics nodesets, instantiate one
``MotionDeviceSystemType`` with a ``MotionDevice`` per robot, and write the readings of :mod:`aioadept.opcua.mapping`
into its variables.

The address space (browse names in the Robotics or DI namespace where the type declares them, this server's own
names in :data:`~aioadept.opcua.mapping.INSTANCE_NS`)::

    Objects/DeviceSet/MotionDeviceSystem                     MotionDeviceSystemType
        MotionDevices/<robot>                                MotionDeviceType (identity, SpeedOverride)
            Axes/Axis1..N (the model's axes)                 AxisType (MotionProfile ROTARY: degrees, degrees
                ParameterSet/ActualPosition, ActualSpeed      per second; LINEAR, a SCARA's J3: mm, mm/s)
            PowerTrains/PowerTrain1..N                       PowerTrainType, Moves -> its axis
                Motor                                        MotorType (nothing known: Bad)
        Controllers/<robot>Controller                        ControllerType, Controls -> the robot
            Software/RobotServer                             SoftwareType (the server's hello)
            TaskControls/RobotServer                         TaskControlType (the program: the robot server)
        SafetyStates/<robot>SafetyState                      SafetyStateType (EmergencyStop from status)

Only Mandatory children and the instances the types' placeholders need are made, plus ActualSpeed (Optional).
Every variable is read-only to clients.
"""

from __future__ import annotations

import asyncio
import datetime
import logging
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from urllib.parse import urlsplit
from typing import Any

from asyncua import Node, Server, ua
from asyncua.common.instantiate_util import instantiate
from asyncua.common.manage_nodes import delete_nodes

from aioadept.opcua.commands import VENDOR_NS
from aioadept.opcua.security import (APPLICATION_URI, UserCertificate, check_modes, client_validator, common_name,
                                     mark_user_certificates, server_certificate, trust_list)
from aioadept.opcua.subscriptions import SharedDataValue, install as _install_subscriptions
from aioadept.opcua.mapping import (DEGREE_CELSIUS, DI_NS, INSTANCE_NS, NODESETS, ROBOTICS_NS, EngineeringUnit, Identity,
                                    Quality, Reading, RobotView)

__all__ = ["CellServer", "STATUS_CODES", "load_nodesets", "without_design_tool_only"]

log = logging.getLogger(__name__)

STATUS_CODES = {q: getattr(ua.StatusCodes, q.value) for q in Quality}
"""Each :class:`~aioadept.opcua.mapping.Quality` as the OPC UA status code its name is."""

_UANODESET = "http://opcfoundation.org/UA/2011/03/UANodeSet.xsd"
# The Robotics and DI namespaces' type ids (OPC 40010-1 and OPC 10000-100, normative).
_ROBOTICS_TYPES = {"MotionDeviceSystemType": 1002, "ControllerType": 1003, "MotionDeviceType": 1004,
                   "TaskControlType": 1011, "SafetyStateType": 1013, "MotorType": 1019, "AxisType": 16601,
                   "PowerTrainType": 16794, "Controls": 4002, "Moves": 18178, "IsDrivenBy": 18180,
                   "HasSafetyStates": 18182}
_DI_SOFTWARE_TYPE = 15106
_DI_DEVICE_SET = 5001
_POLICIES = {"none": ua.SecurityPolicyType.NoSecurity, "sign": ua.SecurityPolicyType.Basic256Sha256_Sign,
             "sign-and-encrypt": ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt}
STOP_WITHIN_S = 2.0
"""How long :meth:`CellServer.stop` waits for asyncua's own stop (a supervisor's grace is 5 s)."""
_PLACEHOLDERS = (ua.ObjectIds.ModellingRule_MandatoryPlaceholder, ua.ObjectIds.ModellingRule_OptionalPlaceholder)


def without_design_tool_only(xml_text: str) -> str:
    """The nodeset ``xml_text`` without its nodes marked ``DesignToolOnly="true"`` (examples for a modelling tool,
    with no parent: a server does not instantiate them, and asyncua's importer refuses a parentless object)."""
    ET.register_namespace("", _UANODESET)
    root = ET.fromstring(xml_text)
    for node in [e for e in root if e.get("DesignToolOnly") == "true"]:
        root.remove(node)
    return ET.tostring(root, encoding="unicode")


async def load_nodesets(server: Server) -> None:
    """Import the package's DI, IA and Robotics nodesets into ``server`` (in that order: each needs the ones
    before it)."""
    folder = resources.files("aioadept.opcua") / "nodesets"
    for name in NODESETS:
        await server.import_xml(xmlstring=without_design_tool_only((folder / name).read_text(encoding="utf-8")))


def _time(epoch_s: float | None) -> datetime.datetime | None:
    if epoch_s is None:
        return None
    return datetime.datetime.fromtimestamp(epoch_s, datetime.timezone.utc)


def _eu(unit: EngineeringUnit) -> ua.EUInformation:
    return ua.EUInformation(NamespaceUri="http://www.opcfoundation.org/UA/units/un/cefact", UnitId=unit.unit_id,
                            DisplayName=ua.LocalizedText(unit.symbol), Description=ua.LocalizedText(unit.name))


class CellServer:
    """An OPC UA server of one cell: ``robots`` (one :class:`~aioadept.opcua.mapping.RobotView` each, in
    :attr:`views`) as MotionDevices of one MotionDeviceSystem. :meth:`start` builds and opens it at ``endpoint``;
    :meth:`refresh` writes what changed in the views since the last call; :meth:`stop` closes it."""

    def __init__(self, endpoint: str, views: Sequence[RobotView], *, commands: Sequence[Any] | None = None,
                 users: dict[str, str] | None = None, security: Sequence[str] = ("none",),
                 certificate: Path | None = None, private_key: Path | None = None, trust: Path | None = None,
                 user_certificates: Path | None = None) -> None:
        names = [v.identity.name for v in views]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"robots {names}: expected at least one, each with its own name")
        if commands is not None and (len(commands) != len(views) or not (users or user_certificates)):
            raise ValueError("commands need one RobotCommands per robot and at least one user")
        if (trust or user_certificates) and "none" in check_modes(security):
            raise ValueError("a trust list or user certificates need sign or sign-and-encrypt only (with none a "
                             "client skips them)")
        self.endpoint = endpoint
        self.views = list(views)
        self.commands = None if commands is None else list(commands)
        self.security = check_modes(security)
        if (certificate is None) != (private_key is None):
            raise ValueError("a certificate needs its private key, and a private key its certificate")
        self.certificate, self.private_key = certificate, private_key
        self.trust, self.user_certificates = trust, user_certificates
        self.users = _Users(users or {})
        self.server = Server(user_manager=self.users)
        # Anonymous sessions read and browse; only a user of the users file may call a method.
        self.server.set_security_policy([_POLICIES[m] for m in self.security], permission_ruleset=_Roles())
        _refuse_writes_as_not_writable(self.server)
        _install_subscriptions()
        self.system: Node | None = None
        self._vars: list[dict[tuple, Node]] = []
        self._written: dict[ua.NodeId, tuple] = {}
        self._idx: dict[str, int] = {}
        self._started = False

    # -- building -----------------------------------------------------------------------------------------------

    async def start(self) -> None:
        s = self.server
        await s.init()
        s.set_endpoint(self.endpoint)
        s.set_server_name("aioadept opcua")
        await s.set_application_uri(APPLICATION_URI)
        if self.security != ("none",):
            cert, key = self.certificate, self.private_key
            if cert is None or key is None:
                cert, key = await server_certificate(urlsplit(self.endpoint).hostname or "localhost")
            await s.load_certificate(str(cert))
            await s.load_private_key(str(key))
        if self.trust is not None:
            s.set_certificate_validator(client_validator(await trust_list(self.trust)))
        tokens = [ua.AnonymousIdentityToken]
        if self.commands and self.users.users:
            tokens.append(ua.UserNameIdentityToken)
        if self.commands and self.user_certificates is not None:
            self.users.certificates = await trust_list(self.user_certificates, "--user-certificates")
            mark_user_certificates(s.iserver)
            tokens.append(ua.X509IdentityToken)
        s.set_identity_tokens(tokens)
        await load_nodesets(s)
        _cache_reference_subtypes(s)
        for uri in (DI_NS, ROBOTICS_NS):
            self._idx[uri] = await s.get_namespace_index(uri)
        self._idx[INSTANCE_NS] = await s.register_namespace(INSTANCE_NS)
        if self.commands:
            self._idx[VENDOR_NS] = await s.register_namespace(VENDOR_NS)
        await self._build()
        await self.refresh(float("-inf"))
        await s.start()
        self._started = True

    async def stop(self, within_s: float = STOP_WITHIN_S) -> int:
        """Close the server within ``within_s`` (nothing to do if it never started; idempotent); returns how many
        client connections it closed.

        Every client connection is aborted first, its unsent bytes dropped: asyncua closes them gracefully and then
        waits until every one has flushed what it still had to send, which a client that stopped reading never
        lets happen. Its clock task (the server's CurrentTime, written every second) is cancelled instead of
        waited for (up to a second). Whatever of asyncua's stop is still running after ``within_s`` is left to the
        process's end, said in one warning."""
        if not self._started:
            return 0
        self._started = False
        iserver = self.server.iserver
        transports = list(iserver.asyncio_transports)
        for transport in transports:
            transport.abort()
        clock, iserver.time_task = iserver.time_task, None
        if clock is not None:
            clock.cancel()
            await asyncio.gather(clock, return_exceptions=True)
        try:
            async with asyncio.timeout(within_s):
                await self.server.stop()
        except TimeoutError:
            log.warning("the OPC UA server's stop took over %g s: left unfinished", within_s)
        return len(transports)

    def _type(self, name: str) -> Node:
        return self.server.get_node(ua.NodeId(_ROBOTICS_TYPES[name], self._idx[ROBOTICS_NS]))

    def _qn(self, name: str, uri: str = INSTANCE_NS) -> ua.QualifiedName:
        return ua.QualifiedName(name, self._idx[uri])

    async def _make(self, parent: Node, type_node: Node, sid: str, name: str) -> Node:
        """An instance of ``type_node`` under ``parent``, node id ``sid`` (a string in this server's namespace),
        browse name ``name``: its Mandatory children only, and none of its placeholders (those are for us to
        fill, with our own names)."""
        nodes = await instantiate(parent, type_node, nodeid=ua.NodeId(sid, self._idx[INSTANCE_NS]),
                                  bname=self._qn(name), dname=ua.LocalizedText(name), instantiate_optional=False)
        placeholders = [n for n in nodes[1:] if (await n.read_browse_name()).Name.startswith("<")]
        if placeholders:
            # Only the new nodes refer to a placeholder's subtree: drop those references here, rather than have
            # asyncua look for references to each deleted node in the whole address space (seconds per node).
            deleted, _ = await delete_nodes(self.server.iserver.isession, placeholders, recursive=True,
                                            delete_target_references=False)
            gone = {n.nodeid for n in deleted}
            aspace = self.server.iserver.aspace
            for n in nodes:
                if n.nodeid not in gone:
                    data = aspace[n.nodeid]
                    data.references = [ref for ref in data.references if ref.NodeId not in gone]
        return nodes[0]

    async def _child(self, node: Node, *path: tuple[str, str]) -> Node:
        return await node.get_child([self._qn(name, uri) for uri, name in path])

    async def _set(self, node: Node, value: Any, vtype: ua.VariantType, quality: Quality = Quality.GOOD) -> None:
        """Write a fixed value; None (nothing known) is written as no value, with ``quality`` saying why."""
        await self.server.write_attribute_value(node.nodeid, SharedDataValue(
            ua.Variant() if value is None else ua.Variant(value, vtype),
            StatusCode=ua.StatusCode(STATUS_CODES[quality])))

    async def _text(self, node: Node, reading: Reading, localized: bool) -> None:
        value = reading.value
        if localized and value is not None:
            value = ua.LocalizedText(value)
        await self._set(node, value, ua.VariantType.LocalizedText if localized else ua.VariantType.String,
                        reading.quality)

    async def _nameplate(self, node: Node, manufacturer: str, model: str, product_code: str, serial: str,
                         identity: Identity) -> None:
        """DI's Manufacturer, Model (LocalizedText), ProductCode, SerialNumber (String): a text not known is Bad."""
        for name, value, localized in (("Manufacturer", manufacturer, True), ("Model", model, True),
                                       ("ProductCode", product_code, False), ("SerialNumber", serial, False)):
            await self._text(await self._child(node, (DI_NS, name)), identity.text(value), localized)

    async def _build(self) -> None:
        s = self.server
        device_set = s.get_node(ua.NodeId(_DI_DEVICE_SET, self._idx[DI_NS]))
        system = self.system = await self._make(device_set, self._type("MotionDeviceSystemType"), "MotionDeviceSystem",
                                                "MotionDeviceSystem")
        r = ROBOTICS_NS
        devices = await self._child(system, (r, "MotionDevices"))
        controllers = await self._child(system, (r, "Controllers"))
        safety = await self._child(system, (r, "SafetyStates"))
        for i, view in enumerate(self.views):
            self._vars.append(await self._build_robot(view.identity, devices, controllers, safety))
            if self.commands is not None:
                await self._add_methods(await devices.get_child([self._qn(view.identity.name)]), self.commands[i])

    async def _add_methods(self, device: Node, commands: Any) -> None:
        """``Stop()`` and ``RunSkill(Skill, Arguments)`` on ``device``, in the vendor namespace, each answering
        the robot server's ack line; a failure is the call's Bad status (BadCommunicationError: no ack came;
        BadInvalidArgument: a skill the protocol cannot carry)."""
        from aioadept.errors import AdeptError

        async def call(work) -> list[ua.Variant] | ua.StatusCode:
            try:
                return [ua.Variant(await work, ua.VariantType.String)]
            except (ValueError, TypeError) as exc:
                log.info("RunSkill refused: %s", exc)
                return ua.StatusCode(ua.StatusCodes.BadInvalidArgument)
            except (AdeptError, OSError, TimeoutError) as exc:
                log.warning("command from OPC UA failed: %s", exc)
                return ua.StatusCode(ua.StatusCodes.BadCommunicationError)

        async def stop(parent: ua.NodeId) -> list[ua.Variant] | ua.StatusCode:
            return await call(commands.stop())

        async def run_skill(parent: ua.NodeId, skill: ua.Variant, args: ua.Variant) -> list[ua.Variant] | ua.StatusCode:
            async def work() -> str:
                if not isinstance(skill.Value, str):
                    raise TypeError(f"Skill: {skill.Value!r} is not a String")
                return await commands.run_skill(skill.Value, [float(v) for v in args.Value or ()])

            return await call(work())

        vidx = self._idx[VENDOR_NS]
        sid = device.nodeid.Identifier
        ack = ua.Argument(Name="Ack", DataType=ua.NodeId(ua.ObjectIds.String), ValueRank=ua.ValueRank.Scalar,
                          Description=ua.LocalizedText("the robot server's ack line"))
        await device.add_method(ua.NodeId(f"{sid}.Stop", vidx), ua.QualifiedName("Stop", vidx), stop, [], [ack])
        skill_arg = ua.Argument(Name="Skill", DataType=ua.NodeId(ua.ObjectIds.String), ValueRank=ua.ValueRank.Scalar,
                                Description=ua.LocalizedText("the skill (V+ program) name"))
        args_arg = ua.Argument(Name="Arguments", DataType=ua.NodeId(ua.ObjectIds.Double),
                               ValueRank=ua.ValueRank.OneDimension, ArrayDimensions=[0],
                               Description=ua.LocalizedText("its numeric arguments"))
        await device.add_method(ua.NodeId(f"{sid}.RunSkill", vidx), ua.QualifiedName("RunSkill", vidx), run_skill,
                                [skill_arg, args_arg], [ack])

    async def _build_robot(self, ident: Identity, devices: Node, controllers: Node, safety: Node) -> dict[tuple, Node]:
        r = ROBOTICS_NS
        n = ident.name
        live: dict[tuple, Node] = {}
        dev = await self._make(devices, self._type("MotionDeviceType"), f"MotionDeviceSystem.{n}", n)
        await self._nameplate(dev, ident.manufacturer, ident.model, ident.product_code, ident.serial_number, ident)
        category = ident.category
        await self._set(await self._child(dev, (r, "MotionDeviceCategory")),
                        None if category is None else int(category), ua.VariantType.Int32,
                        Quality.NOT_EXPOSED if category is None else Quality.GOOD)
        live[("device", "SpeedOverride")] = await self._child(dev, (DI_NS, "ParameterSet"), (r, "SpeedOverride"))
        axes = await self._child(dev, (r, "Axes"))
        trains = await self._child(dev, (r, "PowerTrains"))
        for i in range(1, ident.axes + 1):
            axis = await self._make(axes, self._type("AxisType"), f"MotionDeviceSystem.{n}.Axis{i}", f"Axis{i}")
            if ident.axis_names:
                await axis.write_attribute(ua.AttributeIds.DisplayName, ua.DataValue(ua.Variant(
                    ua.LocalizedText(ident.axis_names[i - 1]), ua.VariantType.LocalizedText)))
            await self._set(await self._child(axis, (r, "MotionProfile")), int(ident.profile(i)),
                            ua.VariantType.Int32)
            params = await self._child(axis, (DI_NS, "ParameterSet"))
            pos = await self._child(params, (r, "ActualPosition"))
            pos_unit, speed_unit = ident.units(i)
            await self._units(pos, pos_unit)
            speed = await self._optional_analog(params, f"MotionDeviceSystem.{n}.Axis{i}.ActualSpeed", "ActualSpeed")
            await self._units(speed, speed_unit)
            live[("axis", i, "ActualPosition")] = pos
            live[("axis", i, "ActualSpeed")] = speed
            train = await self._make(trains, self._type("PowerTrainType"), f"MotionDeviceSystem.{n}.PowerTrain{i}",
                                     f"PowerTrain{i}")
            await train.add_reference(axis.nodeid, self._type("Moves").nodeid, forward=True, bidirectional=True)
            await axis.add_reference(train.nodeid, self._type("IsDrivenBy").nodeid, forward=True, bidirectional=True)
            motor = await self._make(train, self._type("MotorType"), f"MotionDeviceSystem.{n}.PowerTrain{i}.Motor",
                                     "Motor")
            await self._nameplate(motor, "", "", "", "", ident)
            temp = await self._child(motor, (DI_NS, "ParameterSet"), (r, "MotorTemperature"))
            await self._set(temp, None, ua.VariantType.Double, Quality.NOT_EXPOSED)
            await self._units(temp, DEGREE_CELSIUS)
        ctl = await self._make(controllers, self._type("ControllerType"), f"MotionDeviceSystem.{n}Controller",
                               f"{n}Controller")
        await self._nameplate(ctl, ident.manufacturer, ident.controller_model, "", ident.controller_serial_number,
                              ident)
        await ctl.add_reference(dev.nodeid, self._type("Controls").nodeid, forward=True, bidirectional=True)
        software = await self._child(ctl, (r, "Software"))
        sw = await self._make(software, self.server.get_node(ua.NodeId(_DI_SOFTWARE_TYPE, self._idx[DI_NS])),
                              f"MotionDeviceSystem.{n}Controller.Software.RobotServer", "RobotServer")
        await self._text(await self._child(sw, (DI_NS, "Manufacturer")), ident.text("aioadept"), True)
        live[("software", "Model")] = await self._child(sw, (DI_NS, "Model"))
        live[("software", "SoftwareRevision")] = await self._child(sw, (DI_NS, "SoftwareRevision"))
        tasks = await self._child(ctl, (r, "TaskControls"))
        task = await self._make(tasks, self._type("TaskControlType"),
                                f"MotionDeviceSystem.{n}Controller.TaskControls.RobotServer", "RobotServer")
        await self._text(await self._child(task, (DI_NS, "ComponentName")), ident.text("robot server"), True)
        tparams = await self._child(task, (DI_NS, "ParameterSet"))
        for name in ("TaskProgramName", "TaskProgramLoaded"):
            live[("task", name)] = await self._child(tparams, (r, name))
        user = await self._child(ctl, (r, "CurrentUser"), (r, "Level"))
        await self._set(user, None, ua.VariantType.String, Quality.NOT_EXPOSED)
        state = await self._make(safety, self._type("SafetyStateType"), f"MotionDeviceSystem.{n}SafetyState",
                                 f"{n}SafetyState")
        await ctl.add_reference(state.nodeid, self._type("HasSafetyStates").nodeid, forward=True, bidirectional=True)
        sparams = await self._child(state, (DI_NS, "ParameterSet"))
        for name in ("EmergencyStop", "ProtectiveStop", "OperationalMode"):
            live[("safety", name)] = await self._child(sparams, (r, name))
        return live

    async def _optional_analog(self, params: Node, sid: str, name: str) -> Node:
        """The Optional AnalogUnitType variable ``name`` of AxisType's ParameterSet, made as its declaration says
        (Double, read-only)."""
        nodes = await instantiate(params, self.server.get_node(ua.NodeId(ua.ObjectIds.AnalogUnitType)),
                                  nodeid=ua.NodeId(sid, self._idx[INSTANCE_NS]), bname=self._qn(name, ROBOTICS_NS),
                                  dname=ua.LocalizedText(name), instantiate_optional=False)
        node = nodes[0]
        await node.write_attribute(ua.AttributeIds.DataType,
                                   ua.DataValue(ua.Variant(ua.NodeId(ua.ObjectIds.Double), ua.VariantType.NodeId)))
        await node.write_attribute(ua.AttributeIds.ValueRank,
                                   ua.DataValue(ua.Variant(ua.ValueRank.Scalar, ua.VariantType.Int32)))
        return node

    async def _units(self, node: Node, unit: EngineeringUnit) -> None:
        eu = await node.get_child(ua.QualifiedName("EngineeringUnits", 0))
        await self._set(eu, _eu(unit), ua.VariantType.ExtensionObject)

    # -- live values --------------------------------------------------------------------------------------------

    async def refresh(self, now_s: float) -> int:
        """Write every live variable whose value or quality changed since it was last written; returns how many.
        A sample that only confirms a value does not rewrite it: its source timestamp stays the time the value
        last changed, as OPC UA Part 4 defines SourceTimestamp (and a resting arm costs the clients nothing)."""
        written = 0
        for view, nodes in zip(self.views, self._vars, strict=True):
            for key, reading in view.readings(now_s).items():
                node = nodes[key]
                mark = (reading.value, reading.quality)
                if self._written.get(node.nodeid) == mark:
                    continue
                self._written[node.nodeid] = mark
                await self.server.write_attribute_value(node.nodeid, self._data_value(key, reading))
                written += 1
        return written

    @staticmethod
    def _data_value(key: tuple, reading: Reading) -> ua.DataValue:
        """The DataValue of a live reading: its value in the variable's data type (none when there is none), the
        status code of its quality, the robot's time as the source timestamp."""
        v = reading.value
        if v is None:
            variant = ua.Variant()
        elif isinstance(v, bool):
            variant = ua.Variant(v, ua.VariantType.Boolean)
        elif key == ("software", "Model"):
            variant = ua.Variant(ua.LocalizedText(v), ua.VariantType.LocalizedText)
        elif isinstance(v, str):
            variant = ua.Variant(v, ua.VariantType.String)
        else:
            variant = ua.Variant(float(v), ua.VariantType.Double)
        return SharedDataValue(variant, StatusCode=ua.StatusCode(STATUS_CODES[reading.quality]),
                               SourceTimestamp=_time(reading.source_time_s),
                               ServerTimestamp=datetime.datetime.now(datetime.timezone.utc))


class _Users:
    """asyncua's user manager: no user name is an anonymous session (it may read); a name and password of the users
    file, or a user certificate of the user certificates' trust list (named by its common name), is a user (it may
    call the methods); anything else is refused."""

    def __init__(self, users: dict[str, str]) -> None:
        self.users = users
        self.certificates: Any = None
        """The user certificates' TrustStore, when the server takes X509 identity tokens."""

    def get_user(self, iserver: Any, username: str | None = None, password: Any = None, certificate: Any = None):
        from asyncua.crypto.permission_rules import User, UserRole
        from cryptography import x509

        from aioadept.opcua.commands import password_ok

        if isinstance(certificate, UserCertificate):  # an X509 identity token, its signature checked
            if self.certificates is not None and self.certificates.is_trusted(x509.load_der_x509_certificate(
                    certificate)):
                return User(role=UserRole.User, name=common_name(certificate))
            return None
        if username is None:  # an anonymous token (a certificate here is the secure channel's, not a user's)
            return User(role=UserRole.Anonymous)
        if password_ok(self.users, username, password):
            return User(role=UserRole.User, name=username)
        return None


class _Roles:
    """Which requests a role may make: a user all of asyncua's user requests, an anonymous session all but Call
    (refused with BadUserAccessDenied)."""

    def __init__(self) -> None:
        from asyncua.crypto.permission_rules import USER_TYPES, UserRole

        user = {ua.NodeId(t) for t in USER_TYPES}
        self._allowed = {UserRole.Admin: user, UserRole.User: user,
                         UserRole.Anonymous: user - {ua.NodeId(ua.ObjectIds.CallRequest_Encoding_DefaultBinary)}}

    def check_validity(self, user: Any, action_type_id: ua.NodeId, body: Any) -> bool:
        return action_type_id in self._allowed.get(user.role, set())


def _cache_reference_subtypes(server: Server) -> None:
    """Make asyncua's browse look up each reference type's subtypes once: it walks the type tree again for every
    reference of every browsed node (most of the time building the address space took, and of every client's
    browse). The reference types are all in once the nodesets are loaded; none is added after."""
    view = server.iserver.view_service
    walk = view._get_sub_ref
    subtypes: dict[ua.NodeId, frozenset[ua.NodeId]] = {}

    def cached(ref: ua.NodeId) -> frozenset[ua.NodeId]:
        found = subtypes.get(ref)
        if found is None:
            found = subtypes[ref] = frozenset(walk(ref))
        return found

    view._get_sub_ref = cached


def _refuse_writes_as_not_writable(server: Server) -> None:
    """A client's write to a variable whose AccessLevel has no CurrentWrite (every variable here) answers
    BadNotWritable, as OPC UA Part 4 says, instead of asyncua's BadUserAccessDenied (which says a user lacks a right
    another user might have)."""
    service = server.iserver.attribute_service
    write = service.write
    denied = ua.StatusCode(ua.StatusCodes.BadUserAccessDenied)

    async def checked(params: ua.WriteParameters, user: Any = None, **kw: Any) -> list[ua.StatusCode]:
        results = await (write(params, user=user, **kw) if user is not None else write(params, **kw))
        out = []
        for item, result in zip(params.NodesToWrite, results, strict=True):
            if result == denied and item.AttributeId == ua.AttributeIds.Value:
                level = server.iserver.aspace.read_attribute_value(item.NodeId, ua.AttributeIds.AccessLevel)
                if level.Value is not None and level.Value.Value is not None and \
                        not ua.ua_binary.test_bit(level.Value.Value, ua.AccessLevel.CurrentWrite):
                    result = ua.StatusCode(ua.StatusCodes.BadNotWritable)
            out.append(result)
        return out

    service.write = checked
