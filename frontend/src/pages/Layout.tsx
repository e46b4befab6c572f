import { NavLink, Outlet, useNavigate } from "react-router-dom";
import { useAuth } from "../auth/AuthContext";
import { mayOpen } from "../lib/roles";

export function Layout() {
  const { user, logout } = useAuth();
  const navigate = useNavigate();
  return (
    <div className="app">
      <header className="topbar">
        <strong className="brand">Vigil</strong>
        {user && (
          <nav>
            {mayOpen(user.role, "nurse") && (
              <>
                <NavLink to="/nurse" end>Alarms</NavLink>
                <NavLink to="/nurse/history">History</NavLink>
                <NavLink to="/nurse/handover">Handover</NavLink>
                <NavLink to="/nurse/fatigue">Alarm fatigue</NavLink>
              </>
            )}
            {mayOpen(user.role, "annotate") && <NavLink to="/annotate">Annotate</NavLink>}
            {mayOpen(user.role, "engineer") && <NavLink to="/engineer">Engineering</NavLink>}
            {mayOpen(user.role, "admin") && <NavLink to="/admin" end>Users and robots</NavLink>}
            {mayOpen(user.role, "admin") && <NavLink to="/admin/storage">Storage</NavLink>}
          </nav>
        )}
        {user && (
          <span className="who">
            {user.username} · {user.role}
            {user.ward ? ` · ward ${user.ward}` : ""}
            <button type="button" onClick={() => { logout(); navigate("/login"); }}>
              Sign out
            </button>
          </span>
        )}
      </header>
      <Outlet />
    </div>
  );
}
