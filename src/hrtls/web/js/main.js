// Entry point: login (session cookie), then the dashboard of one mission.

import { Api, ApiError } from "./api.js";
import { Dashboard } from "./dashboard.js";

const api = new Api();
const loginSection = document.getElementById("login");
const loginForm = document.getElementById("login-form");
const loginToken = document.getElementById("login-token");
const loginError = document.getElementById("login-error");
const appSection = document.getElementById("app");
let dashboard = null;

function showLogin(message) {
  if (dashboard) dashboard.close();
  dashboard = null;
  window.hrtlsDashboard = null;
  appSection.hidden = true;
  loginSection.hidden = false;
  loginError.hidden = !message;
  loginError.textContent = message || "";
  loginToken.focus();
}

function refusal(err) {
  if (err instanceof ApiError && (err.status === 401 || err.status === 403)) {
    return `Refused: ${err.detail || "token not accepted"}`;
  }
  return `Cannot reach the supervisor: ${err.message}`;
}

async function enter(who) {
  loginSection.hidden = true;
  appSection.hidden = false;
  dashboard = new Dashboard(api, who, { onUnauthorized: () => showLogin("Session ended: sign in again.") });
  window.hrtlsDashboard = dashboard;
  const current = dashboard;
  const attempt = async () => {
    if (dashboard !== current) return;
    try {
      await current.start();
    } catch (err) {
      if (err instanceof ApiError && err.status === 401) { showLogin("Session ended: sign in again."); return; }
      current.setConnection("offline", `waiting for the supervisor (${err.message})`);
      setTimeout(attempt, 2000);
    }
  };
  await attempt();
}

loginForm.addEventListener("submit", async (event) => {
  event.preventDefault();
  const token = loginToken.value.trim();
  loginToken.value = "";
  if (!token) { showLogin("Enter a token."); return; }
  try {
    await enter(await api.login(token));
  } catch (err) {
    showLogin(refusal(err));
  }
});

document.getElementById("logout").addEventListener("click", async () => {
  await api.logout().catch(() => {});
  showLogin("");
});

(async () => {
  try {
    await enter(await api.whoami());
  } catch (err) {
    showLogin(err instanceof ApiError && err.status === 401 ? "" : refusal(err));
  }
  document.body.dataset.ready = "1";
})();
