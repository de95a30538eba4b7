// The pages that are not a session: the landing page at `/` (start a session, or join one by
// its link) and a link that opens nothing (`blocked`: what is wrong, in words, and the ways
// out). See docs/web.md.
import { createSession } from "./api.js";

const $ = (id) => document.getElementById(id);

/// Starts a new session and goes there.
export async function newSession(onError) {
  try {
    const created = await createSession();
    location.assign(`/s/${created.session}#token=${created.token}`);
  } catch (err) {
    onError(`cannot start a session: ${err.message}`);
  }
}

/// The page of a link that opens no session: what is wrong, and the ways out.
export function blocked(text) {
  document.body.classList.add("blocked");
  $("blocked-text").textContent = text;
  $("blocked-new").onclick = () => newSession((m) => ($("blocked-text").textContent = m));
}

export function landing() {
  document.body.classList.add("landing");
  $("landing-new").onclick = () => newSession((m) => ($("join-error").textContent = m));
  $("join").onsubmit = (e) => {
    e.preventDefault();
    let url;
    try {
      url = new URL($("join-link").value.trim(), location.href);
    } catch {
      url = null;
    }
    const ok = url && /^\/s\/[0-9a-fA-F-]{36}$/.test(url.pathname) && new URLSearchParams(url.hash.slice(1)).get("token");
    if (!ok) {
      $("join-error").textContent = "that is not a session link: it looks like …/s/…#token=…; ask for the whole link";
      return;
    }
    location.assign(`${url.pathname}${url.hash}`);
  };
}

