// The EAMOS mission extension: starts `eamos lsp` (stdio) for mission files.
// Everything it shows (errors, completion, hover, definitions, rename) comes from the server;
// see docs/editors.md.
"use strict";

const vscode = require("vscode");
const { LanguageClient, TransportKind } = require("vscode-languageclient/node");

let client;

function serverOptions() {
  const config = vscode.workspace.getConfiguration("eamos");
  const command = config.get("server.command", "eamos");
  const args = ["lsp", ...config.get("server.extraArgs", [])];
  // TransportKind.stdio also passes --stdio, which `eamos lsp` accepts.
  return { command, args, transport: TransportKind.stdio };
}

async function start() {
  client = new LanguageClient(
    "eamos",
    "EAMOS missions",
    serverOptions(),
    { documentSelector: [{ scheme: "file", language: "eamos" }, { scheme: "untitled", language: "eamos" }] }
  );
  await client.start();
}

async function activate(context) {
  context.subscriptions.push(
    vscode.workspace.onDidChangeConfiguration(async (event) => {
      if (event.affectsConfiguration("eamos.server")) {
        await deactivate();
        await start();
      }
    })
  );
  try {
    await start();
  } catch (err) {
    vscode.window.showErrorMessage(
      `EAMOS: could not start "eamos lsp" (${err.message}). Install EAMOS (pip install ...) ` +
        `or set eamos.server.command to the eamos command's path.`
    );
  }
}

async function deactivate() {
  if (client) {
    const running = client;
    client = undefined;
    await running.stop();
  }
}

module.exports = { activate, deactivate };
