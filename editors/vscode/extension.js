// The V+ extension: starts `aioadept vplus lsp` for .V2/.v2/.pg files and runs `aioadept vplus dap` for the
// "vplus" debugger type. The grammar and language configuration are declarative (package.json).
const vscode = require("vscode");
const { LanguageClient } = require("vscode-languageclient/node");

let client;

function command() {
  const cmd = vscode.workspace.getConfiguration("aioadept").get("command") || ["aioadept"];
  return { exe: cmd[0], args: cmd.slice(1) };
}

async function activate(context) {
  const { exe, args } = command();
  client = new LanguageClient("aioadept-vplus", "V+ (aioadept)",
    { command: exe, args: [...args, "vplus", "lsp"] },
    { documentSelector: [{ language: "vplus" }] });
  await client.start();
  context.subscriptions.push(vscode.debug.registerDebugAdapterDescriptorFactory("vplus", {
    createDebugAdapterDescriptor() {
      const { exe: e, args: a } = command();
      return new vscode.DebugAdapterExecutable(e, [...a, "vplus", "dap"]);
    },
  }));
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
