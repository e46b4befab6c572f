import { Link, useLocation } from "react-router-dom";
import { useAuth } from "../auth/AuthContext";
import { homeFor } from "../lib/roles";

/** What a user sees on an address that is no page ("not found") or a page their role may not
 *  open ("not allowed here"), with a way back to their own start page instead of a silent
 *  redirect. */
export function NotHerePage({ kind }: { kind: "not-found" | "forbidden" }) {
  const { user } = useAuth();
  const location = useLocation();
  const home = user ? homeFor(user.role) : "/login";
  return (
    <main className="not-here" data-kind={kind}>
      <h1>{kind === "not-found" ? "Page not found" : "Not allowed here"}</h1>
      <p>
        {kind === "not-found"
          ? `There is no page at ${location.pathname}.`
          : `Your account (${user?.role ?? "signed out"}) may not open ${location.pathname}.`}
      </p>
      <p>
        <Link to={home}>{user ? "Back to your start page" : "Go to sign-in"}</Link>
      </p>
    </main>
  );
}
