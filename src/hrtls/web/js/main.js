// Entry point: login, then the dashboard of one mission.

import { Api, ApiError } from "./api.js";
import { Dashboard } from "./dashboard.js";

const api = new Api("");
const loginSection = document.getElementById("login");
const loginForm = document.getElementById("login-form");
const loginToken = document.getElementById("login-token");
const loginError = document.getElementById("login-error");
const appSection = document.getElementById("app");
let dashboard = null;

function showLogin(message) {
  if (dashboard) dashboard.close();
  dashboard = null;
  appSection.hidden = true;
  loginSection.hidden = false;
  loginError.hidden = !message;
  loginError.textContent = message || "";
  loginToken.focus();
}

async function enter() {
  try {
    const who = await api.whoami();
    loginSection.hidden = true;
    appSection.hidden = false;
    dashboard = new Dashboard(api, who, { onUnauthorized: () => signOut("Session ended.") });
    window.hrtlsDashboard = dashboard;
    await dashboard.start();
  } catch (err) {
    api.setToken(null);
    if (err instanceof ApiError && (err.status === 401 || err.status === 403)) {
      showLogin(`Refused: ${err.detail || "token not accepted"}`);
    } else {
      showLogin(`Cannot reach the supervisor: ${err.message}`);
    }
  }
}

function signOut(message) {
  api.logout().catch(() => {});
  api.setToken(null);
  showLogin(message);
}

loginForm.addEventListener("submit", (event) => {
  event.preventDefault();
  const token = loginToken.value.trim();
  if (!token) { showLogin("Enter a token."); return; }
  api.setToken(token);
  loginToken.value = "";
  enter();
});
document.getElementById("logout").addEventListener("click", () => signOut(""));

if (api.token) enter(); else showLogin("");
document.body.dataset.ready = "1";
