// The page's entry: which page this is. `/` is the landing page (start a session, or join one
// by its link); `/s/{session}#token=…` opens the session (session.js; the token never leaves
// in a URL the server sees); a link without its token, or one the proxy refuses, is said in
// words with a way out (`blocked`), and nothing retries. See docs/web.md.
import { blocked, landing } from "./landing.js";
import { startSession } from "./session.js";

const match = location.pathname.match(/^\/s\/([0-9a-fA-F-]{36})$/);
const token = new URLSearchParams(location.hash.slice(1)).get("token");
if (!match) landing();
else if (!token) blocked("This link has no token (the part after #token=), so it opens nothing. Ask whoever shared it for the whole link, or start a new session.");
else startSession(match[1].toLowerCase(), token);
