// The control protocol (docs/protocol.md) over the daemon's WebSocket: one JSON line per text
// message. Requests are paired with their answers by `id`; events go to `onEvent`. A dropped
// connection is opened again after a pause that grows to a few seconds; whoever uses it hears
// `onOpen` each time, so that it can subscribe again and show the state as it is now.

export class Connection {
  constructor({ onOpen, onClose, onEvent }) {
    this.onOpen = onOpen;
    this.onClose = onClose;
    this.onEvent = onEvent;
    this.nextId = 1;
    this.pending = new Map();
    this.retryMs = 250;
    this.socket = null;
    this.wanted = false;
  }

  open() {
    this.wanted = true;
    const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws";
    const socket = new WebSocket(url);
    this.socket = socket;
    socket.onopen = () => {
      this.retryMs = 250;
      this.onOpen();
    };
    socket.onmessage = (message) => this.receive(message.data);
    socket.onclose = () => {
      if (this.socket !== socket) return;
      this.socket = null;
      for (const [, p] of this.pending) p.reject(new Error("the connection to the cell was lost"));
      this.pending.clear();
      this.onClose();
      if (this.wanted) {
        setTimeout(() => this.wanted && this.open(), this.retryMs);
        this.retryMs = Math.min(this.retryMs * 2, 4000);
      }
    };
  }

  close() {
    this.wanted = false;
    if (this.socket) this.socket.close();
  }

  get isOpen() {
    return this.socket !== null && this.socket.readyState === WebSocket.OPEN;
  }

  receive(text) {
    let message;
    try {
      message = JSON.parse(text);
    } catch {
      return;  // the daemon's lines are JSON; anything else is not ours to show
    }
    if ("event" in message) return this.onEvent(message);
    const waiting = this.pending.get(message.id);
    if (!waiting) return;
    this.pending.delete(message.id);
    waiting.resolve(message);
  }

  // Resolves with the whole response ({ok: true, ...} or {ok: false, error: {code, message}}).
  call(cmd, members = {}) {
    if (!this.isOpen) return Promise.reject(new Error("not connected to the cell"));
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.pending.set(id, { resolve, reject });
      this.socket.send(JSON.stringify({ cmd, id, ...members }));
    });
  }
}

// The login (POST /api/login): the token is exchanged for an HttpOnly cookie the page never sees.
export async function logIn(token) {
  const response = await fetch("/api/login", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ token }),
    credentials: "same-origin",
  });
  return response.json();
}

export async function loggedIn() {
  try {
    const response = await fetch("/api/login", { credentials: "same-origin" });
    return response.ok ? "yes" : "no";
  } catch {
    return "unreachable";
  }
}

export async function logOut() {
  await fetch("/api/logout", { method: "POST", credentials: "same-origin" });
}
