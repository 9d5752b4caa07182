// The drive panel: drives the selected robot through wmd (GET /api/v1/robots/{id}/drive, role driver). While an
// arrow key (with the pad focused) or an on-screen button is held, it sends {"v", "w"} at once and then every
// 100 ms; wmd stops the robot when nothing comes for its hold time (150 ms). It sends a stop at once on release, on
// losing focus (the pad's blur, the window's blur), when the page is hidden or left (visibilitychange, pagehide),
// and closes the socket then, which wmd also takes as a stop. Shows wmd's limits, the robot's status (fault
// included) and its telemetry.

import { el } from './panels.js';

const SEND_PERIOD_MS = 100;
const POLL_PERIOD_MS = 1000;
const KEYS = { ArrowUp: [1, 0], ArrowDown: [-1, 0], ArrowLeft: [0, 1], ArrowRight: [0, -1] };

/** ws(s)://host/api/v1/robots/{id}/drive?role=driver (&token=). */
export function driveUrl(base, robot, token = '') {
  const url = new URL(`/api/v1/robots/${encodeURIComponent(robot)}/drive`, base);
  url.protocol = url.protocol === 'https:' ? 'wss:' : 'ws:';
  url.searchParams.set('role', 'driver');
  if (token) url.searchParams.set('token', token);
  return url.href;
}

/** The command for the held directions: each a [forward, left] pair in {-1, 0, 1}, scaled by the limits. */
export function commandOf(held, limits, fraction) {
  let forward = 0;
  let left = 0;
  for (const [f, l] of held) {
    forward += f;
    left += l;
  }
  forward = Math.max(-1, Math.min(1, forward));
  left = Math.max(-1, Math.min(1, left));
  return { v: forward * limits.max_v * fraction, w: left * limits.max_w * fraction };
}

export class DrivePanel {
  constructor(api, tokenOf) {
    this.api = api;
    this.tokenOf = tokenOf;
    this.robot = '';
    this.socket = null;
    this.limits = { max_v: 0, max_w: 0, hold_ms: 0 };
    this.held = new Map();  // key or button → [forward, left]
    this.timer = null;
    this.sent = 0;
    this.box = document.getElementById('drive-panel');
    this.picker = document.getElementById('drive-robot');
    this.pad = document.getElementById('drive-pad');
    this.speed = document.getElementById('drive-speed');
    this.picker.addEventListener('change', () => this.select(this.picker.value));
    this.pad.addEventListener('keydown', (e) => this.onKey(e, true));
    this.pad.addEventListener('keyup', (e) => this.onKey(e, false));
    this.pad.addEventListener('blur', () => this.releaseAll('blur'));
    for (const button of this.box.querySelectorAll('button[data-drive]')) {
      const direction = button.dataset.drive.split(',').map(Number);
      const press = (e) => {
        e.preventDefault();
        button.setPointerCapture?.(e.pointerId);
        this.hold(button, direction);
      };
      const release = () => this.release(button);
      button.addEventListener('pointerdown', press);
      for (const type of ['pointerup', 'pointercancel', 'lostpointercapture']) button.addEventListener(type, release);
    }
    window.addEventListener('blur', () => this.releaseAll('window blur'));
    document.addEventListener('visibilitychange', () => {
      if (document.visibilityState !== 'visible') this.releaseAll('hidden');
    });
    window.addEventListener('pagehide', () => this.disconnect('pagehide'));
    this.poll();
  }

  /** Drives `robot` from now on (empty: none). */
  select(robot) {
    if (robot === this.robot && this.socket) return;
    this.disconnect('another robot');
    this.refused = false;
    this.robot = robot;
    this.picker.value = robot;
    this.render();
    if (robot) this.connect();
  }

  connect() {
    const socket = new WebSocket(driveUrl(this.api.base, this.robot, this.tokenOf()));
    this.socket = socket;
    this.setState('connecting');
    socket.onopen = () => { if (socket === this.socket) this.setState('open'); };
    socket.onmessage = (e) => { if (socket === this.socket) this.onMessage(e.data); };
    socket.onclose = () => {
      if (socket !== this.socket) return;
      this.socket = null;
      this.held.clear();
      this.stopTimer();
      this.setState('closed');
      // wmd restarted or the network dropped: try again, but not against another driver (busy, replaced).
      if (!this.refused) {
        const robot = this.robot;
        setTimeout(() => { if (robot === this.robot && !this.socket && !this.refused) this.connect(); }, 2000);
      }
    };
  }

  disconnect(why) {
    this.releaseAll(why);
    this.refused = true;  // no reconnection: the page is going, or another robot is chosen (select() clears it)
    if (this.socket) {
      const socket = this.socket;
      this.socket = null;
      socket.close();
    }
    this.setState('closed');
  }

  onMessage(text) {
    let m;
    try { m = JSON.parse(text); } catch { return; }
    if (m.type === 'state') {
      this.limits = { max_v: m.max_v, max_w: m.max_w, hold_ms: m.hold_ms };
      this.robotConnected = m.robot_connected;
      this.command = m.command;
      if (m.telemetry !== undefined) this.telemetry = m.telemetry;
      this.render();
    } else if (m.type === 'error') {
      this.setMessage(`${m.error}: ${m.detail}`);
      if (m.error === 'driver_busy' || m.error === 'replaced') this.refused = true;
    }
  }

  onKey(e, down) {
    const direction = KEYS[e.key];
    if (!direction) return;
    e.preventDefault();
    if (down) {
      if (!e.repeat) this.hold(e.key, direction);
    } else {
      this.release(e.key);
    }
  }

  hold(what, direction) {
    if (!this.socket || this.socket.readyState !== WebSocket.OPEN) return;
    this.held.set(what, direction);
    this.send();
    if (!this.timer) this.timer = setInterval(() => this.send(), SEND_PERIOD_MS);
  }

  release(what) {
    if (!this.held.delete(what)) return;
    if (this.held.size === 0) {
      this.stopTimer();
      this.sendStop();
    } else {
      this.send();
    }
  }

  releaseAll(why) {
    const moving = this.held.size > 0 || this.timer;
    this.held.clear();
    this.stopTimer();
    if (moving) {
      this.sendStop();
      this.setMessage(`stopped (${why})`);
    }
  }

  stopTimer() {
    if (this.timer) clearInterval(this.timer);
    this.timer = null;
  }

  send() {
    if (this.held.size === 0) return;
    const fraction = Number(this.speed.value) / 100;
    this.write(commandOf(this.held.values(), this.limits, fraction));
  }

  sendStop() { this.write({ v: 0, w: 0 }); }

  write(command) {
    if (this.socket && this.socket.readyState === WebSocket.OPEN) {
      this.socket.send(JSON.stringify(command));
      this.sent += 1;
      this.box.dataset.sent = String(this.sent);
      this.box.dataset.last = `${command.v},${command.w}`;
    }
  }

  setState(state) {
    this.box.dataset.state = state;
    document.getElementById('drive-connection').textContent = state;
  }

  setMessage(text) { document.getElementById('drive-message').textContent = text; }

  /** The robots (for the picker) and the selected one's status and telemetry, every second. */
  async poll() {
    try {
      const answer = await this.api.robots();
      const ids = answer.robots.map((r) => r.id);
      const options = [''].concat(ids);
      if (this.picker.options.length !== options.length ||
          options.some((id, i) => this.picker.options[i].value !== id)) {
        this.picker.replaceChildren(...options.map((id) => el('option', { value: id }, id || '(choose a robot)')));
        this.picker.value = this.robot;
      }
      const robot = answer.robots.find((r) => r.id === this.robot);
      this.status = robot?.status ?? '';
      if (robot && robot.telemetry !== undefined) this.telemetry = robot.telemetry;
      if (robot?.drive) this.robotConnected = robot.drive.robot_connected;
      this.render();
    } catch {
      // the server is away: the status panel says so
    }
    setTimeout(() => this.poll(), POLL_PERIOD_MS);
  }

  render() {
    const f = (x, digits = 2) => (typeof x === 'number' ? x.toFixed(digits) : '–');
    document.getElementById('drive-limits').textContent =
      this.robot ? `${f(this.limits.max_v)} m/s, ${f(this.limits.max_w)} rad/s, hold ${this.limits.hold_ms || '–'} ms` : '–';
    const status = document.getElementById('drive-status');
    status.textContent = this.robot
      ? `${this.status || '–'}${this.robotConnected ? ', bridge connected' : ', no bridge connected'}`
      : '–';
    status.dataset.value = this.status || '';
    document.getElementById('drive-command').textContent =
      this.command ? `v ${f(this.command.v)} m/s, w ${f(this.command.w)} rad/s` : '–';
    const body = document.getElementById('drive-telemetry');
    const motors = this.telemetry?.motors ?? [];
    body.replaceChildren(...motors.map((m) => el('tr', { class: m.fault ? 'fault' : '' },
      el('td', {}, String(m.id)),
      el('td', {}, m.current == null ? '–' : String(m.current)),
      el('td', {}, m.temperature == null ? 'n/a' : String(m.temperature)),
      el('td', {}, m.fault ? 'FAULT' : 'ok'),
      el('td', {}, String(m.faults ?? 0)))));
    document.getElementById('drive-telemetry-note').textContent = this.telemetry
      ? `current in ${this.telemetry.current_unit || 'raw'} units; the robot's protocol reports no temperatures`
      : 'no telemetry yet';
  }
}
