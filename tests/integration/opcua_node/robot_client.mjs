// node-opcua's client against `aioadept opcua` (tests/integration/test_opcua_node.py): finds the MotionDeviceSystem
// by browsing from the Objects folder for an object whose type definition is MotionDeviceSystemType in the Robotics
// namespace, subscribes to its six axes' ActualPosition, and reads EmergencyStop and OperationalMode. Writes one JSON
// object per line on stdout: {"found": ...}, then {"axis": i, "value": v, "status": name, "source": ms} for every
// data change, until its standard input closes. Usage: node robot_client.mjs opc.tcp://HOST:PORT
import { AttributeIds, BrowseDirection, ClientMonitoredItem, ClientSubscription, NodeClassMask, OPCUAClient,
         TimestampsToReturn } from "node-opcua-client";

const ROBOTICS = "http://opcfoundation.org/UA/Robotics/";
const DI = "http://opcfoundation.org/UA/DI/";
const HIERARCHICAL = "i=33";
const say = (obj) => process.stdout.write(JSON.stringify(obj) + "\n");

async function children(session, nodeId, objectsOnly) {
  const result = await session.browse({
    nodeId, browseDirection: BrowseDirection.Forward, referenceTypeId: HIERARCHICAL, includeSubtypes: true,
    nodeClassMask: objectsOnly ? NodeClassMask.Object : 0, resultMask: 63,
  });
  return result.references || [];
}

async function child(session, nodeId, ns, name) {
  const found = (await children(session, nodeId, false)).filter(
    (r) => r.browseName.namespaceIndex === ns && r.browseName.name === name);
  if (found.length !== 1) throw new Error(`${nodeId.toString()} has ${found.length} children ${ns}:${name}`);
  return found[0].nodeId;
}

async function findSystem(session, rns) {
  const seen = new Set();
  const todo = ["ns=0;i=85"];  // the Objects folder
  while (todo.length) {
    const node = todo.shift();
    for (const ref of await children(session, node, true)) {
      const id = ref.nodeId.toString();
      if (seen.has(id)) continue;
      seen.add(id);
      if (ref.typeDefinition.namespace === rns) {
        const type = await session.read({ nodeId: ref.typeDefinition, attributeId: AttributeIds.BrowseName });
        if (type.value.value.name === "MotionDeviceSystemType") return ref.nodeId;
      }
      if (ref.nodeId.namespace !== 0) todo.push(ref.nodeId);
    }
  }
  throw new Error("no MotionDeviceSystemType instance under Objects");
}

async function main() {
  const url = process.argv[2];
  const client = OPCUAClient.create({ endpointMustExist: false, connectionStrategy: { maxRetry: 2 } });
  await client.connect(url);
  const session = await client.createSession();
  const namespaces = (await session.read({ nodeId: "ns=0;i=2255", attributeId: AttributeIds.Value })).value.value;
  const rns = namespaces.indexOf(ROBOTICS);
  const dns = namespaces.indexOf(DI);
  const system = await findSystem(session, rns);
  const devices = await child(session, system, rns, "MotionDevices");
  const [device] = await children(session, devices, true);
  const axesFolder = await child(session, device.nodeId, rns, "Axes");
  const axes = (await children(session, axesFolder, true)).sort((a, b) => a.browseName.name < b.browseName.name ? -1 : 1);
  const positions = [];
  for (const axis of axes) {
    const params = await child(session, axis.nodeId, dns, "ParameterSet");
    positions.push(await child(session, params, rns, "ActualPosition"));
  }
  const safety = await child(session, system, rns, "SafetyStates");
  const [state] = await children(session, safety, true);
  const sparams = await child(session, state.nodeId, dns, "ParameterSet");
  const read = async (name) => {
    const dv = await session.read({ nodeId: await child(session, sparams, rns, name), attributeId: AttributeIds.Value });
    return { value: dv.value.value, status: dv.statusCode.name };
  };
  say({ found: system.toString(), device: device.browseName.name, axes: axes.map((a) => a.browseName.name),
        emergencyStop: await read("EmergencyStop"), operationalMode: await read("OperationalMode") });
  const sub = ClientSubscription.create(session, { requestedPublishingInterval: 50, requestedMaxKeepAliveCount: 20,
                                                   requestedLifetimeCount: 600, publishingEnabled: true });
  positions.forEach((nodeId, i) => {
    const item = ClientMonitoredItem.create(sub, { nodeId, attributeId: AttributeIds.Value },
                                            { samplingInterval: 0, queueSize: 10, discardOldest: true },
                                            TimestampsToReturn.Both);
    item.on("changed", (dv) => say({ axis: i + 1, value: dv.value.value, status: dv.statusCode.name,
                                     source: dv.sourceTimestamp ? dv.sourceTimestamp.getTime() : null }));
  });
  say({ subscribed: positions.length });
  await new Promise((resolve) => { process.stdin.on("end", resolve); process.stdin.on("close", resolve);
                                   process.stdin.resume(); });
  await sub.terminate();
  await session.close();
  await client.disconnect();
}

main().catch((err) => { process.stderr.write(`robot_client.mjs: ${err.stack || err}\n`); process.exit(1); });
