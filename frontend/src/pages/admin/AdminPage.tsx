// Admin: users (create, deactivate, reactivate) and robots' tokens (create, rotate, revoke).
import { useEffect, useState, type FormEvent } from "react";
import { api, errorMessage } from "../../api/client";
import type { components } from "../../api/schema";
import type { Role, User } from "../../api/types";
import { useAuth } from "../../auth/AuthContext";

type Robot = components["schemas"]["RobotOut"];
const ROLES: Role[] = ["nurse", "annotator", "engineer", "admin"];

export function AdminPage() {
  const { user: me } = useAuth();
  const [users, setUsers] = useState<User[] | null>(null);
  const [robots, setRobots] = useState<Robot[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [shownToken, setShownToken] = useState<{ robot: string; token: string } | null>(null);

  const load = () => {
    void api.GET("/api/users").then(({ data, error }) => {
      if (data) setUsers(data); else setError(errorMessage(error, "Could not load the users"));
    });
    void api.GET("/api/robots").then(({ data, error }) => {
      if (data) setRobots(data); else setError(errorMessage(error, "Could not load the robots"));
    });
  };
  useEffect(load, []);

  async function setActive(user: User, active: boolean) {
    setError(null);
    const path = { params: { path: { user_id: user.id } } };
    const { error } = active
      ? await api.POST("/api/users/{user_id}/reactivate", path)
      : await api.POST("/api/users/{user_id}/deactivate", path);
    if (error) setError(errorMessage(error, `Could not change ${user.username}`));
    load();
  }

  async function robotToken(robot: Robot, action: "rotate" | "revoke") {
    setError(null);
    setShownToken(null);
    const path = { params: { path: { robot_id: robot.id } } };
    if (action === "rotate") {
      const { data, error } = await api.POST("/api/robots/{robot_id}/token", path);
      if (data) setShownToken({ robot: data.robot_id, token: data.token });
      else setError(errorMessage(error, `Could not rotate the token of ${robot.id}`));
    } else {
      const { error } = await api.DELETE("/api/robots/{robot_id}/token", path);
      if (error) setError(errorMessage(error, `Could not revoke the token of ${robot.id}`));
    }
    load();
  }

  return (
    <main className="page admin">
      <h1>Users and robots</h1>
      {error && <p role="alert" className="error">{error}</p>}

      <h2>Users</h2>
      {users === null ? <p className="muted">Loading…</p> : (
        <table className="table" aria-label="Users">
          <thead><tr><th>User</th><th>Name</th><th>Role</th><th>Ward</th><th>Status</th><th /></tr></thead>
          <tbody>{users.map((u) => (
            <tr key={u.id} data-user={u.username}>
              <td>{u.username}</td><td>{u.display_name}</td><td>{u.role}</td><td>{u.ward ?? "–"}</td>
              <td>{u.active ? "active" : <span className="pill">deactivated</span>}</td>
              <td>
                {u.active
                  ? u.id !== me?.id && <button type="button" onClick={() => void setActive(u, false)}>Deactivate</button>
                  : <button type="button" onClick={() => void setActive(u, true)}>Reactivate</button>}
              </td>
            </tr>))}</tbody>
        </table>
      )}
      <NewUserForm onCreated={load} onError={setError} />

      <h2>Robots</h2>
      {shownToken && (
        <p role="status" className="card token-once">
          New token for {shownToken.robot} (shown once, copy it to the robot now):{" "}
          <code aria-label="new robot token">{shownToken.token}</code>
        </p>
      )}
      {robots === null ? <p className="muted">Loading…</p> : (
        <table className="table" aria-label="Robots">
          <thead><tr><th>Robot</th><th>Name</th><th>Ward</th><th>Connected</th><th>Token</th><th /></tr></thead>
          <tbody>{robots.map((r) => (
            <tr key={r.id} data-robot={r.id}>
              <td>{r.id}</td><td>{r.name}</td><td>{r.ward}</td><td>{r.connected ? "yes" : "no"}</td>
              <td>{r.has_token ? "set" : <span className="pill">revoked</span>}</td>
              <td>
                <button type="button" onClick={() => void robotToken(r, "rotate")}>Rotate token</button>
                {r.has_token && <button type="button" onClick={() => void robotToken(r, "revoke")}>Revoke token</button>}
              </td>
            </tr>))}</tbody>
        </table>
      )}
      <NewRobotForm onCreated={(robot, token) => { setShownToken({ robot, token }); load(); }} onError={setError} />
    </main>
  );
}

function NewUserForm({ onCreated, onError }: { onCreated(): void; onError(message: string): void }) {
  const [username, setUsername] = useState("");
  const [displayName, setDisplayName] = useState("");
  const [password, setPassword] = useState("");
  const [role, setRole] = useState<Role>("nurse");
  const [ward, setWard] = useState("");

  async function submit(event: FormEvent) {
    event.preventDefault();
    const { error } = await api.POST("/api/users", {
      body: { username, password, role, display_name: displayName, ward: ward || null },
    });
    if (error) { onError(errorMessage(error, "Could not create the user")); return; }
    setUsername(""); setDisplayName(""); setPassword(""); setWard("");
    onCreated();
  }

  return (
    <form className="card admin-form" aria-label="New user" onSubmit={(e) => void submit(e)}>
      <label>User name<input value={username} onChange={(e) => setUsername(e.target.value)} required /></label>
      <label>Display name<input value={displayName} onChange={(e) => setDisplayName(e.target.value)} /></label>
      <label>Password<input type="password" autoComplete="new-password" minLength={8} value={password} onChange={(e) => setPassword(e.target.value)} required /></label>
      <label>Role<select value={role} onChange={(e) => setRole(e.target.value as Role)}>{ROLES.map((r) => <option key={r} value={r}>{r}</option>)}</select></label>
      <label>Ward<input value={ward} onChange={(e) => setWard(e.target.value)} placeholder="all wards" /></label>
      <button type="submit">Create user</button>
    </form>
  );
}

function NewRobotForm({ onCreated, onError }: { onCreated(robot: string, token: string): void; onError(message: string): void }) {
  const [id, setId] = useState("");
  const [name, setName] = useState("");
  const [ward, setWard] = useState("");

  async function submit(event: FormEvent) {
    event.preventDefault();
    const { data, error } = await api.POST("/api/robots", { body: { id, name, ward } });
    if (!data) { onError(errorMessage(error, "Could not add the robot")); return; }
    setId(""); setName(""); setWard("");
    onCreated(data.robot_id, data.token);
  }

  return (
    <form className="card admin-form" aria-label="New robot" onSubmit={(e) => void submit(e)}>
      <label>Robot id<input value={id} onChange={(e) => setId(e.target.value)} required /></label>
      <label>Name<input value={name} onChange={(e) => setName(e.target.value)} /></label>
      <label>Ward<input value={ward} onChange={(e) => setWard(e.target.value)} required /></label>
      <button type="submit">Add robot</button>
    </form>
  );
}
